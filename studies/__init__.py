"""Reproductions of the paper, accuracy and speed studies, stress tests.

Each module is a script (``python studies/<name>.py [--quick]``); the test
suite imports them and runs their quick mode.
"""
