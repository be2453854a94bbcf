"""Operator devices beside robosuite's: the scripted expert and its operator profiles (``expert``), and
``VRDevice`` (a Meta Quest or any WebXR headset, through its browser), with the options of its server
(``VRServerOptions``) and of its camera stream (``VRStreamOptions``).

See ``docs/vr.md`` in the repository for setup (USB and Wi-Fi), the controls and the message schema.
"""

import importlib
import os

# robosuite.devices imports pynput for its keyboard device, which needs an X display unless told otherwise; a VR
# session often runs on a headless machine
if not os.environ.get("DISPLAY"):
    os.environ.setdefault("PYNPUT_BACKEND", "dummy")

__all__ = ["VRDevice", "VRServerOptions", "VRStreamOptions"]

# the module of each name, imported on first use: the filters, frames and protocol modules stay usable without
# robosuite loaded
_MODULES = {"VRDevice": "vr.device", "VRServerOptions": "vr.server", "VRStreamOptions": "vr.stream"}


def __getattr__(name):
    if name in _MODULES:
        return getattr(importlib.import_module(f"{__name__}.{_MODULES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
