"""What the quiet-output tests count as a warning in a program's output."""

import re

# a Python warning ("UserWarning: ..."), a log record (robosuite's "[robosuite WARNING]", robomimic's "ROBOMIMIC
# WARNING(", any other logger's through tests/helpers/stage.py's "log record ..."), an error said in passing
WARNING_LINE = re.compile(r"warning\b|\berror\b|^log record ", re.IGNORECASE | re.MULTILINE)


def warning_lines(lines: list[str]) -> list[str]:
    return [line for line in lines if WARNING_LINE.search(line)]
