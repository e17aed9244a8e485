"""The batched PPO loop's arithmetic (``agents.training.batched_ppo``): GAE (P1, P2),
advantage scaling, running mean and variance, the values of the states steps ended in, and the
window of observations the actor reads. Each is a function of tensors, tested by hand in
``tests/test_batched_ppo.py``."""

from __future__ import annotations

from typing import Any

from agents.batched_policy import push_window, role_input


def gae(reward: Any, value: Any, next_value: Any, terminated: Any, done: Any, gamma: float, lam: float) -> Any:
    """Generalized advantage estimates (Schulman et al. 2016) over a rollout of T steps
    (leading axis): (P1) delta_t = r_t + gamma V(s'_t) (1 - terminated_t) - V(s_t), with
    s'_t the state step t ended in (the last state of an episode the cycle limit cut is
    bootstrapped (P2), a terminated one is not); A_t = delta_t + gamma lam (1 - done_t)
    A_t+1: the sum stops where an episode ended, since row t+1 is then a new episode.
    ``terminated`` and ``done`` broadcast against ``reward`` (e.g. (T, B, 1) against
    (T, B, N))."""
    import torch

    adv = torch.zeros_like(reward)
    last = torch.zeros_like(reward[0])
    for t in reversed(range(reward.shape[0])):
        delta = reward[t] + gamma * next_value[t] * (1.0 - terminated[t]) - value[t]
        last = delta + gamma * lam * (1.0 - done[t]) * last
        adv[t] = last
    return adv


def normalize_advantages(adv: Any, real: Any = None, team: Any = None) -> Any:
    """Advantages (M, N) scaled to mean 0 and std 1 over the real beacons' entries (``real``:
    their mask, None: all), over the whole batch or, with ``team`` (M, N) ids, within each team
    (``--norm-advantage-per-team``). A new tensor; entries outside ``real`` are scaled with the
    batch's figures (or, per team, left as they are): the update does not read them."""
    if team is None:
        pick = adv if real is None else adv[real]
        return (adv - pick.mean()) / (pick.std() + 1e-8)
    out = adv.clone()
    for k in team.unique().tolist():
        own = team == k if real is None else (team == k) & real
        if int(own.sum()) > 1:
            out[own] = (adv[own] - adv[own].mean()) / (adv[own].std() + 1e-8)
        else:  # one entry: its advantage less its mean
            out[own] = 0.0
    return out


class RunningNorm:
    """Running mean and variance of vectors of ``shape`` (the parallel update of Chan, Golub &
    LeVeque 1979, as SB3's ``RunningMeanStd``); ``normalize(x)`` = clip((x - mean) /
    sqrt(var + 1e-8), -clip, clip), in float32."""

    def __init__(self, shape: tuple[int, ...], clip: float = 10.0) -> None:
        import torch

        self.mean = torch.zeros(shape, dtype=torch.float64)
        self.var = torch.ones(shape, dtype=torch.float64)
        self.count = 1e-4
        self.clip = clip

    def update(self, x: Any) -> None:
        x = x.reshape(-1, *self.mean.shape).double()
        n = x.shape[0]
        mean, var = x.mean(0), x.var(0, unbiased=False)
        delta, total = mean - self.mean, self.count + n
        self.var = (self.var * self.count + var * n + delta**2 * self.count * n / total) / total
        self.mean = self.mean + delta * n / total
        self.count = total

    def normalize(self, x: Any) -> Any:
        import torch

        z = (x - self.mean.float()) / torch.sqrt(self.var.float() + 1e-8)
        return z.clamp(-self.clip, self.clip)


def next_state_values(value: Any, at_ends: Any, done: Any, last_value: Any) -> Any:
    """V of the state each step ended in, (T, B, N): where the episode went on, that state is
    the next step's, so its value is ``value[t + 1]`` (``last_value`` after the rollout's last
    step); where it ended (``done`` (T, B, 1)), ``at_ends[t]``, the value of the episode's
    last state computed before the reset replaced it."""
    import torch

    following = torch.cat([value[1:], last_value[None]])
    return torch.where(done == 0.0, following, at_ends)


def window_input(window: Any, obs: Any, first: Any, history: int, role_slots: int = 0) -> tuple[Any, Any]:
    """(the window after ``obs`` (..., N, O), the actor's input): with ``history`` 1 the
    observation itself, else ``push_window``'s window (..., N, K, O) and its K observations side
    by side (..., N, K x O), newest first; with ``role_slots`` (= N) each beacon's one-hot index
    after it (``role_input``). Collection, the episode ends' values and validation share it."""
    if history > 1:
        window = push_window(window, obs, first)
        obs = window.flatten(-2)
    return window, role_input(obs, role_slots) if role_slots else obs
