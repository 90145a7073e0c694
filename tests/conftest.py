"""Shared test set-up: this folder is on sys.path, so tests import the helper modules beside it
(``georef_helpers``, ``short_plans``) whether or not their own folder is a package."""
