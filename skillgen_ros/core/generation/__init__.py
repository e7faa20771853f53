"""Demonstration generation (the paper's Algorithm 1) over an environment interface."""
