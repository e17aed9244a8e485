"""Bounds on a training config, checked before anything is allocated or written.

``TrainConfig.check`` and ``RLlibConfig.check`` call ``check_bounds``: every number
must be finite and in a range that fits a machine (``n_envs: 1e7`` would build ten
million simulators, ``net_arch: [2e9]`` a 150 GB layer, ``learning_rate: .inf`` a
run that crashes after its config.yml is written). A ``ConfigError`` (one line)
names the key, the value and the range (``BoundsError`` here, re-raised as
``agents.training.config.ConfigError``).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

from coopnav_env.seeds import MAX_SEED


class BoundsError(ValueError):
    """A bound exceeded (``config`` re-raises it as its own ``ConfigError``)."""


MAX_TIMESTEPS = 10**11
MAX_N_ENVS = 4096
MAX_ROLLOUT = 10**7  # n_steps x n_envs (SB3's rollout buffer rows per beacon)
MAX_EVAL_EPISODES = 100_000
MAX_EVAL_CELLS = 10_000
MAX_ENV_RUNNERS = 1024
MAX_RUN_SEED = 2**32 - 1  # a run's seed seeds numpy's legacy global generator, which takes 32 bits

__all__ = ["BoundsError", "check_bounds"]


def _finite_numbers(value, where: str):
    """Every number in ``value`` (nested lists/dicts) finite; a ConfigError naming the first."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return
    if isinstance(value, numbers.Real):
        try:
            ok = math.isfinite(value)
        except OverflowError:  # an int too large for a float
            ok = False
        if not ok:
            raise BoundsError(f"{where} must be a finite number of a sensible size, got {value!r:.40}")
        return
    if isinstance(value, dict):
        for k, v in value.items():
            _finite_numbers(v, f"{where}.{k}")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _finite_numbers(v, f"{where}[{i}]")


def _int_in(value, low, high, where: str):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= value <= high:
        raise BoundsError(f"{where} must be an integer in [{low}, {high}], got {value!r:.40}")


def _positive(value, where: str, high: float = math.inf):
    _number_in(value, 0.0, high, True, where)


PPO_RANGES = (  # (key, low, high, the low end open): SB3's PPO coefficients
    ("gamma", 0.0, 1.0, True),
    ("gae_lambda", 0.0, 1.0, False),
    ("clip_range", 0.0, 10.0, True),
    ("clip_range_vf", 0.0, 1e6, True),
    ("ent_coef", 0.0, 10.0, False),
    ("vf_coef", 0.0, 100.0, False),
    ("max_grad_norm", 0.0, 1e6, True),
    ("target_kl", 0.0, 100.0, True),
)


def _number_in(value, low: float, high: float, open_low: bool, where: str):
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if ok:
        f = float(value)
        ok = (low < f if open_low else low <= f) and f <= high
    if not ok:
        bracket = "(" if open_low else "["
        raise BoundsError(f"{where} must be a number in {bracket}{low:g}, {high:g}], got {value!r:.40}")


def _net_arch(value, where: str):
    from agents.limits import LimitError, check_net_arch

    try:
        check_net_arch(value, where)
    except LimitError as err:
        raise BoundsError(str(err)) from None


def _eval_cells(cells: dict, where: str):
    n = 1
    for values in (cells or {}).values():
        n *= len(values) if isinstance(values, (list, tuple)) else 1
        if n > MAX_EVAL_CELLS:
            raise BoundsError(f"{where}: the grid has more than {MAX_EVAL_CELLS} cells: refused")


def check_bounds(config: Any) -> None:
    """Refuse (``ConfigError``) a config whose numbers are not finite or out of range."""
    _finite_numbers(config.to_dict(), "config")
    if config.timesteps is not None:
        _int_in(config.timesteps, 1, MAX_TIMESTEPS, "timesteps")
    if config.seed is not None:  # numpy's and torch's global seeds (SB3's set_random_seed, Ray's)
        from coopnav_env.seeds import refuse_test_seeds

        if isinstance(config.seed, numbers.Integral) and not isinstance(config.seed, bool):
            try:  # a test seed is named as one (it is out of range too)
                refuse_test_seeds(config.seed, what="seed")
            except ValueError as err:
                raise BoundsError(str(err)) from None
        _int_in(config.seed, 0, MAX_RUN_SEED, "seed")
    ev = config.eval
    _int_in(ev.episodes, 0, MAX_EVAL_EPISODES, "eval.episodes")
    _int_in(ev.seed, 0, MAX_SEED - max(int(ev.episodes), 1) + 1, "eval.seed")
    _eval_cells(ev.cells, "eval.cells")
    if hasattr(ev, "every_steps"):
        _int_in(ev.every_steps, 0, MAX_TIMESTEPS, "eval.every_steps")
    ppo = config.ppo or {}
    if hasattr(config, "n_envs"):  # stable-baselines3
        _int_in(config.n_envs, 1, MAX_N_ENVS, "n_envs")
        _int_in(config.checkpoint_every_steps, 0, MAX_TIMESTEPS, "checkpoint_every_steps")
        lr = ppo.get("learning_rate", 3e-4)
        if isinstance(lr, str) and lr.startswith("lin_"):
            try:
                lr = float(lr[4:])
            except ValueError:
                lr = None
        if lr is not None and lr != 0:  # a bad text is TrainConfig.check's to report; 0: frozen weights
            _positive(lr, "ppo.learning_rate", 10.0)
        n_steps = ppo.get("n_steps", 2048)
        _int_in(n_steps, 1, MAX_ROLLOUT, "ppo.n_steps")
        if n_steps * config.n_envs > MAX_ROLLOUT:
            raise BoundsError(
                f"ppo.n_steps x n_envs = {n_steps * config.n_envs} rows per rollout, more than {MAX_ROLLOUT}: refused"
            )
        for key, high in (("batch_size", MAX_ROLLOUT), ("n_epochs", 10_000)):
            if key in ppo:
                _int_in(ppo[key], 1, high, f"ppo.{key}")
        # PPO's coefficients in their meaningful ranges: gamma 2 or a negative clip trained
        # without a word (an input audit); "(" an open end. A text (a schedule) is SB3's to read.
        for key, lo, hi, open_low in PPO_RANGES:
            value = ppo.get(key)
            if value is not None and not isinstance(value, str):
                _number_in(value, lo, hi, open_low, f"ppo.{key}")
        kwargs = ppo.get("policy_kwargs") or {}
        if isinstance(kwargs, dict) and "net_arch" in kwargs:
            _net_arch(kwargs["net_arch"], "ppo.policy_kwargs.net_arch")
        norm = config.normalize
        for key in ("clip_obs", "clip_reward", "epsilon"):
            _positive(getattr(norm, key), f"normalize.{key}")
        im = config.imitate
        if im.planner is not None:
            _int_in(im.steps, 1, MAX_TIMESTEPS, "imitate.steps")
            _int_in(im.epochs, 1, 100_000, "imitate.epochs")
            _int_in(im.batch_size, 1, MAX_ROLLOUT, "imitate.batch_size")
    else:  # RLlib
        runners = config.env_runners or {}
        if "num_envs_per_env_runner" in runners:
            _int_in(runners["num_envs_per_env_runner"], 1, MAX_N_ENVS, "env_runners.num_envs_per_env_runner")
        if "num_env_runners" in runners:
            _int_in(runners["num_env_runners"], 0, MAX_ENV_RUNNERS, "env_runners.num_env_runners")
        _int_in(config.checkpoint_every_iterations, 0, 10**9, "checkpoint_every_iterations")
        if "lr" in ppo and isinstance(ppo["lr"], numbers.Real) and ppo["lr"] != 0:
            _positive(ppo["lr"], "ppo.lr", 10.0)
        for key in ("fcnet_hiddens", "head_fcnet_hiddens"):
            if key in (config.model or {}):
                _net_arch(config.model[key], f"model.{key}")
