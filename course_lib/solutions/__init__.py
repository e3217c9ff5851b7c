"""Hidden reference answers and self-checks for the notebooks' exercises, one module per lesson.

Import a lesson's module explicitly, e.g. ``from course_lib.solutions import vae_basics``.
"""
