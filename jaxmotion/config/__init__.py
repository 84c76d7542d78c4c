"""Configuration: ``key=value`` overrides of typed frozen dataclasses, their validation (ranges
declared next to each field, rules on each class: ``checks.py``), experiment files, user errors.

The lowest layer: it imports nothing else of jaxmotion, so every layer may raise its errors.
"""

from jaxmotion.config.checks import AllowInf, Max, Min, NonEmpty, Ordered, Problem, Range, validate
from jaxmotion.config.errors import ConfigError, JaxmotionError, cli_errors
from jaxmotion.config.experiments import ENV_EXPERIMENTS, experiments_root, list_experiments, load, load_experiment
from jaxmotion.config.overrides import apply_overrides, from_dict, to_dict

__all__ = [
    "ConfigError",
    "JaxmotionError",
    "cli_errors",
    "ENV_EXPERIMENTS",
    "experiments_root",
    "list_experiments",
    "load",
    "load_experiment",
    "apply_overrides",
    "from_dict",
    "to_dict",
    "validate",
    "AllowInf",
    "Max",
    "Min",
    "NonEmpty",
    "Ordered",
    "Problem",
    "Range",
]
