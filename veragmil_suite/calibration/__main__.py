import sys

from veragmil_suite.calibration.benchmark import main

sys.exit(main())
