"""One module per CLI command: ``HELP``, ``add_arguments(parser)``, ``run(args) -> int``.

A module imports at its top only what its arguments need; what the command runs (numpy,
OpenCV, rasterio, zenoh, JSBSim ...) is imported inside ``run``, so that ``--help`` answers
at once (tests/test_cli_startup.py, benchmarks/bench_cli.py).
"""
