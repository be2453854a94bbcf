"""Teleoperation devices: ``VRDevice`` (a Meta Quest or any WebXR headset, through its browser).

See ``README_VR.md`` beside this file for setup (USB and Wi-Fi), the controls and the message schema.
"""

import os

# robosuite.devices imports pynput for its keyboard device, which needs an X display unless told otherwise; a VR
# session often runs on a headless machine
if not os.environ.get("DISPLAY"):
    os.environ.setdefault("PYNPUT_BACKEND", "dummy")

__all__ = ["VRDevice"]


def __getattr__(name):
    # imported on first use: the filters, frames and protocol modules stay usable without robosuite loaded
    if name == "VRDevice":
        from veragmil_suite.devices.vr import VRDevice

        return VRDevice
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
