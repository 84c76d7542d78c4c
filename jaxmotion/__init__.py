"""jaxmotion: physically simulated characters trained from motion capture, end to end in JAX."""

__version__ = "0.1.0"
