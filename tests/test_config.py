"""Tests of jaxmotion.config: overrides, JSON round trips and experiment loading."""

from __future__ import annotations

import dataclasses
import json
import pathlib
import textwrap
from typing import Literal

import pytest

from jaxmotion import config
from jaxmotion.config import ConfigError


@dataclasses.dataclass(frozen=True)
class Ppo:
    learning_rate: float = 3e-4
    epochs: int = 5
    clip: float = 0.2
    normalize_adv: bool = True


@dataclasses.dataclass(frozen=True)
class Net:
    hidden: tuple[int, ...] = (1024, 512)
    activation: Literal["relu", "relu6", "tanh"] = "relu6"
    init_log_std: float | None = None


@dataclasses.dataclass(frozen=True)
class Disc:
    ensemble: int = 32
    gp_weight: float = 10.0


@dataclasses.dataclass(frozen=True)
class Experiment:
    name: str = "toy"
    seed: int | None = 0
    ppo: Ppo = Ppo()
    net: Net = Net()
    disc: Disc | None = None
    groups: tuple[str, ...] = ("upper", "lower")
    weights: tuple[tuple[str, float], ...] = (("upper", 0.25), ("lower", 0.75))
    scales: dict[str, float] = dataclasses.field(default_factory=lambda: {"a": 1.0})
    span: tuple[float, float] = (0.8, 1.2)
    out: pathlib.Path = pathlib.Path("runs")


def test_round_trip_is_exact_and_json_able():
    cfg = Experiment(
        seed=None,
        disc=Disc(ensemble=4),
        net=Net(hidden=(64,), init_log_std=-1.0),
        weights=(("upper", 0.5), ("lower", 0.5)),
    )
    d = config.to_dict(cfg)
    back = config.from_dict(Experiment, json.loads(json.dumps(d)))
    assert back == cfg
    assert isinstance(back.net.hidden, tuple)
    assert isinstance(back.weights[0], tuple)
    assert isinstance(back.disc, Disc)
    assert config.from_dict(Experiment, config.to_dict(Experiment())) == Experiment()


def test_from_dict_rejects_unknown_key_and_bad_type():
    with pytest.raises(ConfigError, match="learning_rate"):
        config.from_dict(Experiment, {"ppo": {"learnig_rate": 1.0}})
    with pytest.raises(ConfigError, match="ppo.epochs"):
        config.from_dict(Experiment, {"ppo": {"epochs": "five"}})


def test_nested_override_does_not_mutate():
    cfg = Experiment()
    new = config.apply_overrides(cfg, ["ppo.learning_rate=1e-3", "ppo.epochs=8", "name=run a"])
    assert new.ppo == Ppo(learning_rate=1e-3, epochs=8)
    assert new.name == "run a"
    assert cfg == Experiment()
    assert new.net is cfg.net  # untouched sections are shared, not copied


@pytest.mark.parametrize("text", ["1,2,3", "(1,2,3)", "[1, 2, 3]", " (1, 2, 3) "])
def test_tuple_parsing(text):
    assert config.apply_overrides(Experiment(), [f"net.hidden={text}"]).net.hidden == (1, 2, 3)


def test_tuple_edge_cases():
    cfg = Experiment()
    assert config.apply_overrides(cfg, ["net.hidden=7"]).net.hidden == (7,)
    assert config.apply_overrides(cfg, ["net.hidden=()"]).net.hidden == ()
    assert config.apply_overrides(cfg, ["groups=arms,body"]).groups == ("arms", "body")
    assert config.apply_overrides(cfg, ['groups=["a", "b"]']).groups == ("a", "b")
    assert config.apply_overrides(cfg, ["span=0.9,1.1"]).span == (0.9, 1.1)
    with pytest.raises(ConfigError, match="span"):
        config.apply_overrides(cfg, ["span=1,2,3"])


@pytest.mark.parametrize(
    "text, expected",
    [("true", True), ("false", False), ("1", True), ("0", False), ("True", True)],
)
def test_bool_parsing(text, expected):
    new = config.apply_overrides(Experiment(), [f"ppo.normalize_adv={text}"])
    assert new.ppo.normalize_adv is expected


def test_bool_rejects_other_words():
    with pytest.raises(ConfigError, match="normalize_adv"):
        config.apply_overrides(Experiment(), ["ppo.normalize_adv=maybe"])


def test_none_parsing():
    cfg = Experiment()
    assert config.apply_overrides(cfg, ["seed=none"]).seed is None
    assert config.apply_overrides(cfg, ["seed=null"]).seed is None
    assert config.apply_overrides(cfg, ["seed=3"]).seed == 3
    assert config.apply_overrides(cfg, ["net.init_log_std=-2"]).net.init_log_std == -2.0
    assert config.apply_overrides(cfg, ["net.init_log_std=None"]).net.init_log_std is None


def test_override_into_none_section_uses_defaults():
    new = config.apply_overrides(Experiment(), ["disc.ensemble=8"])
    assert new.disc == Disc(ensemble=8)
    assert config.apply_overrides(new, ["disc=none"]).disc is None


def test_mapping_overrides():
    cfg = Experiment()
    new = config.apply_overrides(cfg, ["weights.upper=0.5", "scales.a=2"])
    assert new.weights == (("upper", 0.5), ("lower", 0.75))
    assert new.scales == {"a": 2.0}
    whole = config.apply_overrides(cfg, ['weights={"arms": 0.1, "body": 0.9}'])
    assert whole.weights == (("arms", 0.1), ("body", 0.9))
    assert config.apply_overrides(cfg, ["weights=arms:0.1,body:0.9"]).weights == whole.weights
    with pytest.raises(ConfigError, match="upper, lower"):
        config.apply_overrides(cfg, ["weights.uper=0.5"])


def test_literal_and_path():
    cfg = config.apply_overrides(Experiment(), ["net.activation=tanh", "out=/tmp/x"])
    assert cfg.net.activation == "tanh"
    assert cfg.out == pathlib.Path("/tmp/x")
    with pytest.raises(ConfigError, match="activation"):
        config.apply_overrides(Experiment(), ["net.activation=gelu"])


def test_unknown_choice_lists_the_choices_and_suggests():
    with pytest.raises(ConfigError) as err:
        config.apply_overrides(Experiment(), ["net.activation=rellu"])
    msg = str(err.value)
    assert msg == "net.activation=rellu: must be one of 'relu', 'relu6', 'tanh' (did you mean 'relu'?)"
    with pytest.raises(ConfigError, match="net.activation=swish: must be one of 'relu', 'relu6', 'tanh'$"):
        config.from_dict(Experiment, {"net": {"activation": "swish"}})


def test_typo_lists_valid_keys_and_suggests():
    with pytest.raises(ConfigError) as err:
        config.apply_overrides(Experiment(), ["ppo.learnig_rate=1e-3"])
    msg = str(err.value)
    assert "ppo.learnig_rate" in msg
    assert "did you mean 'ppo.learning_rate'" in msg
    for key in ("learning_rate", "epochs", "clip", "normalize_adv"):
        assert key in msg
    with pytest.raises(ConfigError, match="seed"):
        config.apply_overrides(Experiment(), ["sed=1"])


def test_bad_value_names_key_value_and_type():
    with pytest.raises(ConfigError) as err:
        config.apply_overrides(Experiment(), ["ppo.epochs=many"])
    msg = str(err.value)
    assert "ppo.epochs" in msg and "'many'" in msg and "int" in msg
    with pytest.raises(ConfigError, match="float"):
        config.apply_overrides(Experiment(), ["ppo.clip=abc"])
    with pytest.raises(ConfigError, match="int"):
        config.apply_overrides(Experiment(), ["net.hidden=1,x"])


def test_malformed_overrides():
    with pytest.raises(ConfigError, match="key=value"):
        config.apply_overrides(Experiment(), ["ppo.epochs"])
    with pytest.raises(ConfigError, match="not a config section"):
        config.apply_overrides(Experiment(), ["ppo.epochs.x=1"])
    with pytest.raises(ConfigError):
        config.apply_overrides(Experiment(), "ppo.epochs=1")


def test_config_error_is_value_error():
    assert issubclass(ConfigError, ValueError)


_EXPERIMENT_FILE = textwrap.dedent(
    """
    from __future__ import annotations
    import dataclasses

    @dataclasses.dataclass(frozen=True)
    class Cfg:
        upper: str = "chest_open"
        lower: str = "squat"
        hidden: tuple[int, ...] = (8, 8)

    def config() -> Cfg:
        return Cfg()
    """
)


@pytest.fixture
def experiments(tmp_path):
    (tmp_path / "composite").mkdir()
    (tmp_path / "composite" / "chest_open+squat.py").write_text(_EXPERIMENT_FILE)
    (tmp_path / "smoke.py").write_text(_EXPERIMENT_FILE.replace('"chest_open"', '"smoke"'))
    (tmp_path / "_common.py").write_text("X = 1\n")
    (tmp_path / "noconfig.py").write_text("X = 1\n")
    return tmp_path


def test_list_experiments(experiments):
    assert config.list_experiments(experiments) == ["composite/chest_open+squat", "noconfig", "smoke"]


def test_load_experiment_with_slash_and_plus(experiments):
    cfg = config.load_experiment("composite/chest_open+squat", experiments)
    assert (cfg.upper, cfg.lower, cfg.hidden) == ("chest_open", "squat", (8, 8))
    # Its own dataclass (with string annotations) works with the generic helpers.
    new = config.apply_overrides(cfg, ["hidden=4,4"])
    assert new.hidden == (4, 4)
    assert config.from_dict(type(cfg), config.to_dict(new)) == new
    assert config.load_experiment("smoke", experiments).upper == "smoke"


def test_load_with_overrides(experiments):
    cfg = config.load("smoke", ["lower=lunge"], experiments)
    assert cfg.lower == "lunge"


def test_env_var_sets_root(experiments, monkeypatch):
    monkeypatch.setenv(config.ENV_EXPERIMENTS, str(experiments))
    assert config.experiments_root() == experiments.resolve()
    assert config.load_experiment("smoke").upper == "smoke"


def test_unknown_experiment_lists_available(experiments):
    with pytest.raises(ConfigError) as err:
        config.load_experiment("composite/chest_open+squaat", experiments)
    msg = str(err.value)
    assert "composite/chest_open+squat" in msg and "smoke" in msg
    assert "did you mean" in msg
    assert "_common" not in msg


def test_bad_experiment_files(experiments):
    with pytest.raises(ConfigError, match="config"):
        config.load_experiment("noconfig", experiments)
    with pytest.raises(ConfigError, match="bad experiment name"):
        config.load_experiment("../smoke", experiments)
