"""course_lib: the small tested library behind the motion-synthesis course.

Layers (imports point down only): rotations -> skeleton -> motion -> bvh,
render, synthetic -> representations, datasets -> models -> training,
evaluation.  Importing course_lib has no side effects.
"""

__version__ = "0.1.0"
