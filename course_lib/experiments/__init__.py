"""Lesson experiments: data, training and evaluation of one paper's models, run by course_lib.reproduce.

One module per lesson (vae_lstm.py: lesson 02; gmm_rnn.py: lesson 03; hvrnn.py: lesson 05), each
registered in course_lib.reproduce.EXPERIMENTS.  Nothing runs at import time.
"""
