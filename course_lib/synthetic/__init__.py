"""Procedural synthetic human motion: subjects, locomotion with control, actions, noise.

    from course_lib.synthetic import make_subjects, generate_locomotion, generate_action, add_noise
    subjects = make_subjects(8, seed=0)
    clip = generate_locomotion(subjects[0], None, duration=4.0, fps=120, seed=1)   # random control program
    jump = generate_action(subjects[1], "jump", style="B", seed=2)
    noisy = add_noise(clip, seed=3)                                                 # noisy.meta["clean"] is clip

Modules: subjects (bone proportions, style A/B), locomotion (control programs, gait phase,
footholds, swing), actions (walk, jog, jump, lift), body (pose from targets: two-bone IK legs
and arms, pelvis lowering), ik (rotations, IK, FK on matrices), noise (jitter, spikes, dropped
frames), report (`python -m course_lib.synthetic.report`: realism figures).

What the data has: ground-truth contacts and control, planted feet (skate ~1 cm/s), heel-toe
roll, gait-dependent cadence/duty/bob, turning lean, ballistic jumps, per-subject bones.
What real mocap has that it lacks: no balance/dynamics (the centre of mass is not checked
against the support), no foot/ground deformation, hands and head are simple (no fingers,
no gaze targets), the same cyclic template for every step (only parameters vary), no
long-range intent or hesitation, no marker noise unless `add_noise` is applied.
"""

from course_lib.synthetic.actions import ACTIONS, generate_action
from course_lib.synthetic.locomotion import (
    GAITS,
    ControlProgram,
    generate_locomotion,
    integrate_root,
    random_control_program,
)
from course_lib.synthetic.noise import add_noise
from course_lib.synthetic.subjects import Subject, make_subject, make_subjects

__all__ = ["ACTIONS", "GAITS", "ControlProgram", "Subject", "add_noise", "generate_action", "generate_locomotion",
           "integrate_root", "make_subject", "make_subjects", "random_control_program"]
