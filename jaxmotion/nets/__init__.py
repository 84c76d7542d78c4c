"""Flax networks as (init, apply) pairs: Gaussian policy, multi-head critic, discriminators."""
