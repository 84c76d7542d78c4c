"""Policies that run without JAX: a run's policy as ONNX or StableHLO, from MuJoCo states to PD
targets (``policy.py``, ``formats.py``), the command (``cli.py``) and a standalone checker that
replays it in plain MuJoCo (``check_policy.py``; it imports neither JAX nor jaxmotion)."""
