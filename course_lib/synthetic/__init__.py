"""Procedural synthetic human motion: subjects, locomotion with control, actions, noise.

Public API: make_subject, make_subjects, random_control_program, ControlProgram,
generate_locomotion (see locomotion.py).
"""

from course_lib.synthetic.actions import ACTIONS, generate_action
from course_lib.synthetic.locomotion import (
                                             GAITS,
                                             ControlProgram,
                                             generate_locomotion,
                                             integrate_root,
                                             random_control_program,
)
from course_lib.synthetic.subjects import Subject, make_subject, make_subjects

__all__ = ["ACTIONS", "GAITS", "ControlProgram", "Subject", "generate_action", "generate_locomotion",
           "integrate_root", "make_subject", "make_subjects", "random_control_program"]
