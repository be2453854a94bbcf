"""Controller buttons to operator commands: which button does what, and press/hold detection.

The hand that drives the robot ("main", right by default) engages with squeeze; its other buttons act on the
episode and the scale; the other hand's buttons act on the view and the mapping. Episode-ending buttons must be
held for half a second, so a brush of the thumb does not throw a demonstration away.

Default bindings (right-handed operator; on the left controller "a"/"b" are the X/Y buttons):

=======================  ==========================  ===========================================
control                  command                     effect
=======================  ==========================  ===========================================
right squeeze (hold)     engage                      the hand drives the end-effector (clutch)
right trigger            grasp                       gripper command (no effect on the spoon)
right A (hold 0.5 s)     ``keep``                    end the episode and keep it
right B (hold 0.5 s)     ``discard``                 end the episode and discard it
right stick press        ``precision``               toggle precision (translation scale x0.25)
right stick up / down    ``scale_up`` / ``down``     translation scale x1.25 / /1.25
left X (hold 0.5 s)      ``reset``                   reset the environment (episode not kept)
left Y                   ``recenter``                operator's forward := camera's forward
left stick press         ``mode``                    toggle relative / absolute
left trigger             ``depth``                   show / hide the depth panel
=======================  ==========================  ===========================================
"""

from __future__ import annotations

from dataclasses import dataclass

from veragmil_suite.devices.vr.protocol import ControllerState

EVENTS = ("keep", "discard", "reset", "recenter", "precision", "mode", "scale_up", "scale_down", "depth")
CONTROLS = ("a", "b", "stick_press", "trigger", "squeeze", "stick_up", "stick_down")


@dataclass(frozen=True)
class Binding:
    """One control of one hand ("main" drives the robot, "other" is the free hand) raising one event.

    hold_s = 0 fires on the press; hold_s > 0 fires once when the control has been held that long.
    """

    hand: str
    control: str
    event: str
    hold_s: float = 0.0

    def __post_init__(self):
        if self.hand not in ("main", "other") or self.control not in CONTROLS or self.event not in EVENTS:
            raise ValueError(f"invalid binding {self}")


DEFAULT_BINDINGS = (
    Binding("main", "a", "keep", 0.5),
    Binding("main", "b", "discard", 0.5),
    Binding("main", "stick_press", "precision"),
    Binding("main", "stick_up", "scale_up"),
    Binding("main", "stick_down", "scale_down"),
    Binding("other", "a", "reset", 0.5),
    Binding("other", "b", "recenter"),
    Binding("other", "stick_press", "mode"),
    Binding("other", "trigger", "depth"),
)

# analog controls count as pressed above PRESS and released below RELEASE (hysteresis: no chatter near the edge)
PRESS = 0.7
RELEASE = 0.3


def _level(state: ControllerState, control: str) -> float:
    if control in ("a", "b", "stick_press"):
        return 1.0 if getattr(state, control) else 0.0
    if control == "stick_up":
        return float(state.stick[1])
    if control == "stick_down":
        return -float(state.stick[1])
    return float(getattr(state, control))


class ButtonEvents:
    """Turns successive controller states into command events (press edges and long presses).

    Args:
        bindings: the ``Binding`` table
        main_hand (str): "right" or "left", the hand that drives the robot
    """

    def __init__(self, bindings: tuple[Binding, ...] = DEFAULT_BINDINGS, main_hand: str = "right"):
        if main_hand not in ("right", "left"):
            raise ValueError("main_hand must be 'right' or 'left'")
        self.bindings = tuple(bindings)
        self.main_hand = main_hand
        self.reset()

    def reset(self) -> None:
        """Forget what is held (a new connection starts with every button up)."""
        self._pressed = [False] * len(self.bindings)
        self._since = [0.0] * len(self.bindings)
        self._fired = [False] * len(self.bindings)

    def _hand(self, which: str) -> str:
        other = "left" if self.main_hand == "right" else "right"
        return self.main_hand if which == "main" else other

    def update(self, controllers: dict[str, ControllerState | None], t: float) -> list[str]:
        """Events raised by these controller states at time t (seconds); an absent controller releases all."""
        events = []
        for i, b in enumerate(self.bindings):
            state = controllers.get(self._hand(b.hand))
            level = 0.0 if state is None else _level(state, b.control)
            pressed = level > PRESS or (self._pressed[i] and level > RELEASE)
            if pressed and not self._pressed[i]:
                self._since[i], self._fired[i] = t, False
            self._pressed[i] = pressed
            if pressed and not self._fired[i] and t - self._since[i] >= b.hold_s:
                self._fired[i] = True
                events.append(b.event)
        return events
