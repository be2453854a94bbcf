"""How far a scoop got: the stages in order, and the furthest one an episode reached."""

# How far a scoop got, in order; a state's stage comes from the simulator state alone (ScoopGranular.scoop_stage),
# so any agent's episode is labelled the same way: its furthest stage, and "held" once success has held.
SCOOP_STAGES = ("start", "reached pile", "loaded spoon", "lifted clear", "at post-scoop pose", "held")


class StageTracker:
    """The furthest of SCOOP_STAGES an episode reached, from each step's info; "held" when its last step succeeds
    (the episode's success, as its metrics count it)."""

    def __init__(self):
        self.index = 0
        self.success = False

    def update(self, info: dict) -> None:
        stage = info.get("stage")
        if stage in SCOOP_STAGES:
            self.index = max(self.index, SCOOP_STAGES.index(stage))
        self.success = bool(info.get("success", False))

    @property
    def stage(self) -> str:
        return SCOOP_STAGES[-1] if self.success else SCOOP_STAGES[self.index]
