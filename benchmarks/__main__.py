"""``python -m benchmarks [--quick] [--output FILE]``: the course's benchmark report.

The same as ``kalman-course bench``; see :mod:`kalman_course.tooling.bench`.
"""

import sys

from kalman_course.tooling.bench import main

sys.exit(main())
