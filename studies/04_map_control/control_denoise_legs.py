"""Lesson 04 side experiment (issue 16): after the MAP filter, hold the toes still with the legs alone.

studies/04_map_control/control_denoise_plant.py held the filter's flagged toes with lesson 03's `plant_feet` on the root and the leg
angles: the flagged toes stopped, but the root moved and the joint error rose from 1.1 to 4.2 cm, and 92 % of the skate
left came from toes under 5 cm whose bit was off.  This tool runs the filter without its planting step
(``DenoiseConfig(plant=False)``, the MAP estimate alone), then four post-steps on its output:

- lesson 03's `plant_feet` on the root and the legs, the estimate's pose contacts (control_denoise_plant.py's setting);
- the legs alone (`planting.plant_legs` columns), the estimate's pose contacts only (foot low and slow);
- `plant_legs`: the legs alone, the pose contacts or a toe under 5 cm (design.py's stance rule), at sigma_slide 3 mm
  (lesson 03's) and 1 mm (the shipped ``DenoiseConfig.plant_sigma_slide``, picked on the tuning clips, through
  `plant_with_prior` as `denoise` does).

On the tuning clips (held-out clips 4-7 of each gait) and the scored clips (0-3, denoise_eval's): mean and max joint
error to the clean motion, foot skate (and the clean clips'), contact agreement.

    python studies/04_map_control/control_denoise_legs.py --out studies/04_map_control/control_denoise_legs_results.json   # ~3 min, one core

Writes nothing to checkpoints/.
"""

import time

import numpy as np
from control_denoise_plant import planted, tuning_and_scored  # the script's own folder is on sys.path

from course_lib.control import DenoiseConfig, denoise
from course_lib.control.design import default_prior
from course_lib.control.planting import plant_legs, plant_with_prior
from course_lib.datasets import noisy_copies
from course_lib.evaluation import foot_skate
from course_lib.experiments import control as C
from course_lib.models.contact_cleanup import leg_columns

COMMAND = "python studies/04_map_control/control_denoise_legs.py --out studies/04_map_control/control_denoise_legs_results.json"


def legs(m) -> list:
    """The leg-angle columns the shipped RNN's training data vary (as the shipped denoise plants with)."""
    return leg_columns(m.skeleton, default_prior().fixed)


POST = {"MAP estimate alone (plant=False)": lambda m: m,
        "plant_feet, root + legs, pose contacts": planted,
        "legs alone, pose contacts": lambda m: planted(m, legs(m)),
        "plant_legs, contacts or toe < 5 cm, sigma_slide 3 mm": lambda m: plant_legs(m, legs(m), sigma_slide=0.003),
        "plant_legs, contacts or toe < 5 cm, 1 mm (shipped)": lambda m: plant_with_prior(m, default_prior())}


def score_set(clips: list, seed: int = 0) -> dict:
    noisy = noisy_copies(clips, seed + 1)
    t0 = time.perf_counter()
    out = [denoise(n, seed=seed, config=DenoiseConfig(plant=False)) for n in noisy]
    res = {"seconds": {"denoise": time.perf_counter() - t0}}
    for name, post in POST.items():
        t0 = time.perf_counter()
        rows = [C._denoise_scores(post(m), c) for m, c in zip(out, clips, strict=True)]
        res["seconds"][name] = time.perf_counter() - t0
        res[name] = {s: float(np.mean([r[s] for r in rows])) for s in rows[0]}
    res["noisy"] = {s: float(np.mean([C._denoise_scores(n, c)[s] for n, c in zip(noisy, clips, strict=True)]))
                    for s in ("mean_joint_error_m", "max_joint_error_m", "foot_skate_m_s", "contact_agreement")}
    res["clean_foot_skate_m_s"] = float(foot_skate(clips))
    return res


def main() -> None:
    tuning_and_scored(score_set, COMMAND, __doc__.splitlines()[0], digits=5)


if __name__ == "__main__":
    main()
