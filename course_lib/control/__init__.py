"""MAP motion control with the GMM-RNN as a prior (Wang, Chai et al. 2021, sec. 5): offline design, online
control, denoising, initial-state estimation.  Taught in notebooks/04_map_control.ipynb.

    from course_lib.control import design_motion, OnlineController, denoise
    m = design_motion([[0, 0], [0, 4]], seconds=4.0, gait="walk")

Modules (one concept each): rnn_prior (eq. 15-16), energy (eq. 17-18), kinematics (eq. 4 in torch), window
(eq. 19 on a window), rollout (the sampler as a function of its noise), pso, lbfgs, design (sec. 5.2), online
(eq. 20-23), denoise (eq. 24-25), lowpass (zero-phase filters: baselines and denoise's start), dropouts (held
frames), spikes (outlier joints), planting (feet held after a search), initial_state (eq. 26), starts (held-out
start frames).
"""

from course_lib.control.denoise import DenoiseConfig, denoise
from course_lib.control.design import DesignConfig, design_motion
from course_lib.control.initial_state import estimate_initial_state
from course_lib.control.online import OnlineConfig, OnlineController
from course_lib.control.pso import PsoConfig, pso
from course_lib.control.rnn_prior import RnnPrior

__all__ = ["DenoiseConfig", "DesignConfig", "OnlineConfig", "OnlineController", "PsoConfig", "RnnPrior", "denoise",
           "design_motion", "estimate_initial_state", "pso"]
