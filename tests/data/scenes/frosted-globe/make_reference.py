"""Mitsuba 3 reference of frosted-globe (python3 make_reference.py --spp 16384, from this folder):
../mitsuba_reference.py with eight full-size 256-spp renders, whose largest error against the
reference is frosted_globe_test.cc's tolerance."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from mitsuba_reference import make_reference  # noqa: E402

make_reference(full_256=8)
