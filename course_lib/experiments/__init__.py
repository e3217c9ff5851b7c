"""Lesson experiments: data, training and evaluation of one paper's models, run by course_lib.reproduce.

One module per lesson (gmm_rnn.py: lesson 03; hvrnn.py: lesson 05).  Lesson 02's lives in
course_lib/reproduce.py itself.  Nothing runs at import time.
"""
