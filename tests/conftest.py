"""Shared pytest set-up: quick notebook settings and a non-interactive matplotlib backend."""

import os

import matplotlib

matplotlib.use("Agg")
# Notebooks executed by nbmake inherit this: small settings in CI.
os.environ.setdefault("SUNLAB_QUICK", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
