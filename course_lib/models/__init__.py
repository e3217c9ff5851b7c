"""The course's models, one file per paper (plus the lesson-01 pose VAE and the baselines).

Import from the submodules, e.g. ``from course_lib.models.vae import PoseVae, VaeConfig``;
this package imports nothing at import time so one broken model cannot break the others.
"""
