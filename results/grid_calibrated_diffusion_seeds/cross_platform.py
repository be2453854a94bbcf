"""
The same agents' episodes on two platforms, matched by (training seed, food, episode): how many end the same way,
and the ones that differ, with each one's place in the second journal (to see whether a stretch of it stands out).

    python results/grid_calibrated_diffusion_seeds/cross_platform.py GPU_JOURNAL CPU_JOURNAL
"""

import json
import sys


def load(path: str) -> dict:
    episodes = {}
    for place, line in enumerate(open(path)):
        r = json.loads(line)["record"]
        episodes[(r["agent"].rsplit(" ", 1)[1], r["food"], r["episode"])] = dict(r, place=place)
    return episodes


first, second = load(sys.argv[1]), load(sys.argv[2])
common = sorted(set(first) & set(second), key=lambda k: second[k]["place"])
same = sum(first[k]["success"] == second[k]["success"] for k in common)
print(f"{len(common)} episodes on both: {same} end the same way, {len(common) - same} differ")
print(
    f"successes: {sum(first[k]['success'] for k in common)} first, {sum(second[k]['success'] for k in common)} second"
)
# this session's CPU journal: places 47-86 ran while the test suite shared the 2 cores
for lo, hi in ((0, 47), (47, 87), (87, 10**6)):
    keys = [k for k in common if lo <= second[k]["place"] < hi]
    if keys:
        print(
            f"places {lo}-{hi}: {len(keys)} episodes, successes {sum(first[k]['success'] for k in keys)} first,"
            f" {sum(second[k]['success'] for k in keys)} second"
        )
for k in common:
    if first[k]["success"] != second[k]["success"]:
        a, b = first[k], second[k]
        print(f"  place {b['place']}: seed {k[0]} {k[1]} episode {k[2]}: {a['stage']} / {b['stage']}")
