"""Makes this scene's Mitsuba 3 reference (reference.exr, reference-x4.exr, reference.json).

Run from this folder, (64 x 48):
  python3 make_reference.py --spp 16384
What it renders and records: ../mitsuba_reference.py, with eight full-size 256-spp renders
against the reference (seeds 1 ... 8: the largest of their errors is the tolerance of
mesh_lamps_test.cc).
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from mitsuba_reference import make_reference  # noqa: E402

make_reference(full_256=8)
