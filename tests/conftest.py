"""Shared test set-up: this folder is on sys.path, so tests import the helper modules beside it
(``georef_helpers``, ``short_plans``) whether or not their own folder is a package."""

from hypothesis import settings

# No per-example deadline: Hypothesis times examples by the wall clock, which the other xdist
# worker (or any load) can stretch past its 200 ms default; the properties are what is tested.
settings.register_profile("air-sitl", deadline=None)
settings.load_profile("air-sitl")
