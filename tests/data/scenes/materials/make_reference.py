"""Makes this scene's Mitsuba 3 reference (reference.exr, reference-x4.exr, reference.json).

Run from this folder:  python3 make_reference.py --spp 4096
What it renders and records: ../mitsuba_reference.py.
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from mitsuba_reference import make_reference  # noqa: E402

make_reference()
