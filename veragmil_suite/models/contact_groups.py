"""Collision bitmasks (MuJoCo contype / conaffinity) of the scene.

Two geoms touch when (contype1 & conaffinity2) or (contype2 & conaffinity1). Grains never test against the
arm's links (nothing in the task needs it, and the pile would pay for every broad-phase pair), the bowl's shell
does not rub on the table (its high-friction foot does), and everything else touches what it physically should.
"""

ROBOT = 1  # robosuite's default bit: arm links, table, floor
FOOD = 2  # grains
DISH = 4  # spoon and bowl shells
FOOT = 8  # the bowl's foot ring, the only part of the bowl that rests on the table

GRAIN = dict(contype=FOOD, conaffinity=FOOD | DISH)
SHELL = dict(contype=DISH, conaffinity=FOOD | DISH)
BOWL_FOOT = dict(contype=FOOT, conaffinity=0)
SUPPORT = dict(contype=ROBOT, conaffinity=ROBOT | FOOD | DISH | FOOT)  # table top and floor
