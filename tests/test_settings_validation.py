"""Settings validation (``config/checks.py``): ranges declared next to each field, rules between
fields on their class, checked where a config is made (overrides, JSON, a learner built in Python,
an environment) before anything is built. Nothing here compiles."""

from __future__ import annotations

import dataclasses
import json
from typing import Annotated, Literal

import pytest

from conftest import REPO
from jaxmotion import config as C
from jaxmotion.config import AllowInf, ConfigError, Max, Min, NonEmpty, Ordered, Problem, Range, validate
from jaxmotion.config.checks import check_fits, problems, size

# ---- the validator on its own ------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Group:
    name: Annotated[str, NonEmpty()] = "full"
    frames: Annotated[int, Min(2)] = 5
    speed: Annotated[tuple[float, float], Min(0, open=True), Ordered()] = (1.0, 1.0)
    weight: Annotated[float, Min(0)] | None = None


@dataclasses.dataclass(frozen=True)
class Toy:
    n: Annotated[int, Min(1)] = 4
    gamma: Annotated[float, Range(0, 1, hi_open=True)] = 0.9
    limit: Annotated[float, Min(0, open=True), AllowInf()] = 1.0
    cap: Annotated[int, Max(10)] = 3
    free: float = 0.0
    mode: Literal["a", "bb"] = "a"
    hidden: Annotated[tuple[int, ...], Min(1)] = (8, 8)
    groups: tuple[Group, ...] = (Group(),)
    weights: tuple[tuple[str, Annotated[float, Min(0)]], ...] = (("upper", 0.5), ("lower", 0.5))
    chunk: Annotated[int, Min(1)] = 2
    total: Annotated[int, Min(1)] = 4

    def checks(self):
        if self.total % self.chunk:
            yield Problem("total", f"must be a multiple of chunk ({self.chunk})")


def lines(cfg) -> list[str]:
    return problems(cfg)


def test_defaults_pass_and_validate_returns_the_config():
    cfg = Toy()
    assert lines(cfg) == []
    assert validate(cfg) is cfg


@pytest.mark.parametrize(
    "change, line",
    [
        (dict(n=0), "n=0: must be ≥ 1"),
        (dict(gamma=1.0), "gamma=1: must be in [0, 1)"),
        (dict(gamma=float("nan")), "gamma=nan: must be a finite number"),
        (dict(free=float("inf")), "free=inf: must be a finite number"),
        (dict(limit=float("nan")), "limit=nan: must be a finite number"),
        (dict(limit=0.0), "limit=0: must be > 0"),
        (dict(cap=11), "cap=11: must be ≤ 10"),
        (dict(mode="b"), "mode=b: must be one of 'a', 'bb' (did you mean 'bb'?)"),
        (dict(hidden=(8, 0)), "hidden[1]=0: must be ≥ 1"),
        (dict(groups=(Group(), Group(frames=1))), "groups[1].frames=1: must be ≥ 2"),
        (dict(groups=(Group(name=""),)), "groups[0].name='': must not be empty"),
        (dict(groups=(Group(speed=(1.2, 0.8)),)), "groups[0].speed=1.2,0.8: must be in increasing order"),
        (dict(groups=(Group(speed=(0.0, 1.0)),)), "groups[0].speed[0]=0: must be > 0"),
        (dict(groups=(Group(weight=-1.0),)), "groups[0].weight=-1: must be ≥ 0"),
        (dict(weights=(("upper", -0.5), ("lower", 0.5))), "weights.upper=-0.5: must be ≥ 0"),
        (dict(total=5), "total=5: must be a multiple of chunk (2)"),
        (dict(n="4"), "n=4: must be a whole number, not a str"),
        (dict(n=True), "n=true: must be a whole number, not a bool"),
        (dict(free="x"), "free=x: must be a number, not a str"),
        (dict(hidden=[8]), "hidden=8: must be a tuple, not a list"),
    ],
)
def test_each_broken_range_is_named_by_its_full_key(change, line):
    got = lines(dataclasses.replace(Toy(), **change))
    assert len(got) == 1 and got[0].startswith(line), got


def test_inf_where_allowed_and_none_for_optional():
    assert lines(Toy(limit=float("inf"), groups=(Group(weight=None), Group(weight=0.0)))) == []


def test_every_problem_in_one_line_and_rules_wait_for_the_fields():
    cfg = Toy(n=0, gamma=2.0, chunk=0, total=5)  # total % chunk would divide by zero
    with pytest.raises(ConfigError) as err:
        validate(cfg, prefix="toy")
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.split("; ") == ["toy.n=0: must be ≥ 1", "toy.gamma=2: must be in [0, 1)", "toy.chunk=0: must be ≥ 1"]
    assert lines(Toy(total=5)) and not problems(Toy(total=5), rules=False)


def test_overrides_and_json_are_validated_at_the_end():
    cfg = C.apply_overrides(Toy(), ["chunk=3", "total=6"])  # valid only once both are applied
    assert (cfg.chunk, cfg.total) == (3, 6)
    with pytest.raises(ConfigError, match=r"^gamma=1.5: must be in \[0, 1\)$"):
        C.apply_overrides(Toy(), ["gamma=1.5"])
    with pytest.raises(ConfigError, match=r"groups\[0\].frames=0: must be ≥ 2"):
        C.apply_overrides(Toy(), ['groups=[{"frames": 0}]'])
    with pytest.raises(ConfigError, match="weights.upper=-1: must be ≥ 0"):
        C.apply_overrides(Toy(), ["weights.upper=-1"])
    with pytest.raises(ConfigError, match="hidden"):
        C.from_dict(Toy, {"hidden": [0]})
    with pytest.raises(ConfigError, match=r"mode=c: must be one of 'a', 'bb'"):
        C.apply_overrides(Toy(), ["mode=c"])


def test_memory_check_names_the_key_and_the_estimate():
    check_fits("ppo.num_envs", 10, 100, "the environments", available=1000)
    with pytest.raises(ConfigError) as err:
        check_fits("ppo.num_envs", 10**9, 200_000, "the environments", available=16 * 10**9)
    msg = str(err.value)
    assert msg.startswith("ppo.num_envs=1000000000: the environments would need about 200.0 TB (200.0 kB each)")
    assert "16.0 GB" in msg
    assert size(512) == "512 B"


# ---- the project's configs ---------------------------------------------------------------------


@pytest.mark.parametrize("name", C.list_experiments())
def test_every_experiment_validates(name):
    cfg = C.load_experiment(name)
    assert problems(cfg) == []
    assert C.from_dict(type(cfg), json.loads(json.dumps(C.to_dict(cfg)))) == cfg  # validated again


@pytest.mark.parametrize("entry", sorted(p.parent.name for p in (REPO / "pretrained").glob("*/config.json")))
def test_pretrained_configs_validate(entry):
    from jaxmotion.training import checkpoint as ckpt
    from jaxmotion.training.learner import TrainConfig

    _, cfg = ckpt.read_config(REPO / "pretrained" / entry, TrainConfig)
    assert problems(cfg) == []


def test_choices_match_the_registries():
    from jaxmotion.algos import disc as D
    from jaxmotion.envs.humanoid import EnvConfig
    from jaxmotion.nets.networks import ACTIVATIONS
    from jaxmotion.physics import arena, backends, sim
    from jaxmotion.tasks import TASKS, TaskConfig
    from jaxmotion.training.hparams import DiscConfig, NetConfig
    from typing import get_args, get_type_hints

    def choices(cls, field):
        return set(get_args(get_type_hints(cls)[field]))

    assert choices(NetConfig, "activation") == set(ACTIVATIONS)
    assert choices(DiscConfig, "loss") == set(D.LOSSES)
    assert choices(DiscConfig, "gp_mode") == set(D.GP_MODES)
    assert choices(sim.PhysicsConfig, "backend") == set(backends.BACKENDS)
    assert choices(arena.ArenaConfig, "sport") == set(arena.SPORTS)
    assert choices(TaskConfig, "name") == set(TASKS)
    assert choices(EnvConfig, "players") == {1, 2}


def test_a_learner_made_in_python_is_checked_before_anything_is_built(monkeypatch):
    from jaxmotion.training import learner as L

    monkeypatch.setattr(L, "make_env", lambda cfg: pytest.fail("the environment was built"))
    cfg = C.load_experiment("smoke")
    for bad, key in (
        (dataclasses.replace(cfg, ppo=dataclasses.replace(cfg.ppo, gamma=1.5)), "ppo.gamma=1.5"),
        (dataclasses.replace(cfg, iterations=7), "iterations=7"),
        (dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, groups=())), "env.groups=()"),
    ):
        with pytest.raises(ConfigError, match=key.replace("(", r"\(").replace(")", r"\)")):
            L.Learner(bad)


def test_an_environment_is_checked_before_it_loads_anything(monkeypatch):
    from jaxmotion.envs import humanoid as H

    monkeypatch.setattr(H, "load_motionlib", lambda *a, **k: pytest.fail("clips were loaded"))
    with pytest.raises(ConfigError, match=r"env.groups=\(\): must not be empty"):
        H.HumanoidEnv(H.EnvConfig(groups=()))
    with pytest.raises(ConfigError, match=r"env.episode_steps=0"):
        H.HumanoidEnv(H.EnvConfig(episode_steps=0))


def test_bench_settings_are_one_line(capsys):
    from jaxmotion import bench

    for flags, key in (
        (["--steps", "0"], "steps=0"),
        (["--batches", "0,4"], "batches[0]=0"),
        (["--backends", "x"], "backends"),
    ):
        assert bench.main(["--quick", "--parts", "physics", *flags]) == 2
        err = capsys.readouterr().err
        assert err.count("error:") == 1 and key in err, err
