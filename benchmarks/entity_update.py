"""What one PPO minibatch of the entity network costs: forward and backward passes on real
observations, this code's encoder against an earlier commit's.

    python benchmarks/entity_update.py                              # gao_lawnmower's three teams
    python benchmarks/entity_update.py --against c1272f6 --repeats 5
    python benchmarks/entity_update.py --encoder deepsets --history 1 --team '{}'

The observations are the loop's (``agents.training.batched_ppo.make_env``): the entity view of
``--scenario`` over the ``--team`` settings (default: the trial's team, two survey vehicles,
two beacon AUVs: the run over numbers of beacons in docs/training/marl.md#levers-state-slots),
512 environments reset and stepped ``--warm-steps`` times with random actions, every beacon
slot of every environment a row (a one-beacon team's padded slot a copy of its beacon's, as the
loop pads it). The rows are tiled to a minibatch of ``--minibatch`` env-steps, each with a
window of ``--history`` observations, as the loop's update feeds them to the actor (IPPO's
critic is a second network of the same size: twice this).

Times ``agents.batched_policy.entity_net`` (the encoder, then the 128x128 head) forward plus
backward of the outputs' sum, the median of ``--repeats`` after one untimed pass, on one torch
thread. ``--against COMMIT`` loads ``agents/entity.py`` of that commit (``git show``) with the
same weights and times it on the same rows, and gives the largest difference of the outputs.
A script, not a test: run it on an idle machine.
"""

from __future__ import annotations

import importlib.util
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_TEAMS = ["{}", "{n_survey: 2}", "{beacon_kinds: [beacon_auv, beacon_auv]}"]


def observations(scenario: str, teams: list[dict], n_envs: int, warm_steps: int, seed: int) -> Any:
    """(rows, ENTITY_DIM) float32: every beacon slot of ``n_envs`` environments of the loop's
    environment after ``warm_steps`` random steps."""
    import torch

    from agents.training.batched_ppo import BatchedPPOConfig, make_env

    config = BatchedPPOConfig(
        scenario=scenario, n_envs=n_envs, teams=teams, critic="observation", entity={"encoder": "attention"}
    )
    env = make_env(config)
    td = env.reset()
    gen = torch.Generator().manual_seed(seed)
    for _ in range(warm_steps):
        obs = td.get(("beacons", "observation"))
        action = torch.rand(*obs.shape[:2], env.action_dim, generator=gen) * 2 - 1
        td.set(("beacons", "action"), action)
        td = env.step_and_maybe_reset(td)[1]
    obs = td.get(("beacons", "observation"))
    return obs.reshape(-1, obs.shape[-1]).float()


def encoder_from_commit(commit: str) -> Any:
    """``agents/entity.py``'s ``EntityEncoder`` as it was at ``commit``."""
    text = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{commit}:agents/entity.py"], check=True, capture_output=True, text=True
    ).stdout
    path = Path(tempfile.mkdtemp()) / "entity_then.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("agents.entity_then", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "agents"
    spec.loader.exec_module(module)
    return module.EntityEncoder


def time_pass(net: Any, x: Any, repeats: int) -> float:
    """Median seconds of one forward and backward pass (after one untimed pass)."""
    times = []
    for i in range(repeats + 1):
        net.zero_grad(set_to_none=True)
        t0 = time.perf_counter()
        net(x).sum().backward()
        if i:
            times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="gao_lawnmower")
    p.add_argument("--team", action="append", help="a team's settings (YAML), repeatable; default: three teams")
    p.add_argument("--encoder", default="attention", choices=["attention", "deepsets"])
    p.add_argument("--history", type=int, default=4, help="the window's observations per row (the loop's --history)")
    p.add_argument("--minibatch", type=int, default=32768, help="env-steps per minibatch (the loop's default)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--warm-steps", type=int, default=20)
    p.add_argument("--against", help="a git commit whose agents/entity.py to time beside this one")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    for name in ("history", "minibatch", "repeats"):
        if getattr(args, name) < 1:
            print(
                f"entity_update.py: --{name.replace('_', '-')} must be at least 1, got {getattr(args, name)}",
                file=sys.stderr,
            )
            return 2
    import torch
    import yaml

    from agents import batched_policy
    from coopnav_env.entity_obs import ENTITY_DIM

    try:
        teams = [yaml.safe_load(t) for t in (args.team or DEFAULT_TEAMS)]
        rows = observations(args.scenario, teams, 512, args.warm_steps, 0)
        then = encoder_from_commit(args.against) if args.against else None
    except yaml.YAMLError as err:  # a team that is not YAML: its first line (PyYAML's runs to five, with a caret)
        where = (
            f" (line {err.problem_mark.line + 1}, column {err.problem_mark.column + 1})"
            if getattr(err, "problem_mark", None)
            else ""
        )
        print(
            f"entity_update.py: --team is not YAML{where}: {getattr(err, 'problem', None) or str(err).splitlines()[0]}",
            file=sys.stderr,
        )
        return 2
    except (ValueError, TypeError, subprocess.CalledProcessError) as err:
        msg = err.stderr.strip() if isinstance(err, subprocess.CalledProcessError) else err
        print(f"entity_update.py: {' '.join(str(msg).split())}", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    slots = rows.shape[0] // 512  # beacon slots per environment
    n = args.minibatch * slots * args.history  # encoder rows of one minibatch
    x = rows.repeat(-(-n // rows.shape[0]), 1)[:n].reshape(args.minibatch, slots, args.history * ENTITY_DIM)
    torch.manual_seed(0)
    kwargs = {"encoder": args.encoder, "embed_dim": 64, "heads": 4}
    net = batched_policy.entity_net(kwargs, (128, 128), 2, 0.01, args.history)
    result: dict[str, Any] = {
        "scenario": args.scenario,
        "teams": teams,
        "encoder": args.encoder,
        "history": args.history,
        "minibatch_env_steps": args.minibatch,
        "beacon_slots": slots,
        "this_s": time_pass(net, x, args.repeats),
    }
    if then is not None:
        old = batched_policy.entity_net(kwargs, (128, 128), 2, 0.01, args.history)
        old.encoder = then(**kwargs)
        old.load_state_dict(net.state_dict())
        with torch.no_grad():
            result["max_output_difference"] = float((old(x) - net(x)).abs().max())
        result["against"] = args.against
        result["then_s"] = time_pass(old, x, args.repeats)
    if args.json:
        print(json.dumps(result, indent=1))
        return 0
    per_step = 1e3 / args.minibatch
    print(
        f"{args.scenario}, {len(teams)} team(s), {slots} beacon slot(s), {args.encoder}, window {args.history}: "
        f"one minibatch of {args.minibatch} env-steps, forward + backward, one thread"
    )
    print(f"  this code      {result['this_s']:.2f} s ({result['this_s'] * per_step:.3f} ms an env-step)")
    if then is not None:
        print(f"  at {args.against:<10}  {result['then_s']:.2f} s ({result['then_s'] * per_step:.3f} ms an env-step)")
        print(
            f"  speed-up {result['then_s'] / result['this_s']:.2f}x; "
            f"outputs differ by at most {result['max_output_difference']:.1e}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
