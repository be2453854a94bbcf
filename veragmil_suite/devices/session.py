"""What a recording session asks of a teleoperation device beyond robosuite's Device (start_control, input2action):
one interface, with a robosuite device's answers as defaults, so the collection loop never probes a device.
"""

from __future__ import annotations

from typing import Any


class SessionDevice:
    """The session hooks of a teleoperation device. The defaults are those of a device with no clutch, no status
    line and no server (robosuite's keyboard, SpaceMouse, DualSense, viewer); the VR device overrides them."""

    # an episode starts at the operator's first squeeze (a clutched device): until then nothing is recorded
    clutched = False
    # what ended the episode from the device ("keep", "discard", "reset"), None while it runs
    episode_command: str | None = None

    @property
    def engaged(self) -> bool:
        """Whether the operator is driving now (always, without a clutch)."""
        return True

    def show_status(self, text: str) -> None:
        """A line for the operator (what to do next), where the device can show one."""

    def set_recording(self, on: bool) -> None:
        """Whether the episode is being recorded, shown to the operator where the device can."""

    def show_progress(self, text: str) -> None:
        """The collection's state (episode, kept and discarded counts, file), where the device can show it."""

    @property
    def asks_verdict(self) -> bool:
        """Whether the operator keeps or discards an episode that ended by itself with a button of this device."""
        return False

    def connection_counters(self) -> dict[str, int] | None:
        """The device's connection counters (a server's), None when it has none."""
        return None

    def close_session(self, farewell: str | None = None) -> None:
        """Ends the device's part in the session (``farewell``: its last words to the operator)."""


class RobosuiteDevice(SessionDevice):
    """One of robosuite's own devices behind the session interface: input passes through, the hooks are defaults."""

    def __init__(self, device):
        self.device = device

    def start_control(self) -> None:
        self.device.start_control()

    def input2action(self, **kwargs: Any) -> dict | None:
        return self.device.input2action(**kwargs)
