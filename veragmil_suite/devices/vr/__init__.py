"""The VR device: a WebXR page served to the headset's browser (server, TLS, connections, stream), the messages it
sends (protocol), and what turns them into robosuite actions (frames, filters, clutch, controls, device).
"""
