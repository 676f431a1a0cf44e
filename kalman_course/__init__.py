"""kalman-course: reference implementations, data, checks and tooling for the course.

Importing the package has no side effects: it sets no print options, no plotting style
and no random state. Import the submodule you need, for example
``from kalman_course import kf``.
"""

__version__ = "0.1.0"
