"""course_lib: the small tested library behind the motion-synthesis course.

Layers (imports point down only; tests/test_import_layers.py holds the table):
rotations, skeleton -> motion -> synthetic, bvh, render, representations ->
datasets, corpus -> models -> training, evaluation -> control -> experiments
-> benchmark -> reproduce.  Importing course_lib has no side effects.
"""

__version__ = "0.1.0"
