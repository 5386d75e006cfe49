"""``python -m mr_damper_bringup.report OUT``: the summary of a finished suite run."""
import sys

from mr_damper_bringup.report.summary import main

sys.exit(main())
