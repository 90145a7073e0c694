"""Helpers for users' own tests: a served vehicle as a pytest fixture (:mod:`.pytest_plugin`)."""
