"""Train a PPO beacon policy on a coopnav scenario (the command line of agents.training).

    python train.py --scenario sousa_asv --timesteps 2000000 --seed 0 --out runs/sousa_ppo
    python train.py --resume runs/sousa_ppo          # continue an interrupted run (either backend)
    python train.py --backend rllib --scenario sousa_asv --timesteps 2000000 --num-env-runners 8 \
        --out runs/sousa_rllib                       # Ray RLlib instead (pip install -e ".[rllib]")
    python train.py --help                           # every option, its default, the scenarios

The same command is installed as ``coopnav-train``. Everything lives in the
``agents.training`` package, which this file only calls:

* ``agents.training.config``: the typed config of a job (``TrainConfig`` for
  stable-baselines3, ``RLlibConfig`` for RLlib), read from configs/ppo/<scenario>.yml
  (configs/rllib/ for RLlib; else default.yml there; or ``--config FILE``), then
  ``--set KEY=VALUE``, ``--n-envs`` and ``--seed`` on top. An unknown key is a
  one-line error naming the closest valid one.
* ``agents.training.sb3``: ``train(config, out)``, readable top to bottom.
* ``agents.training.rllib``: the same on Ray RLlib (Tune grids with ``--tune``).
* ``agents.training.scoring``: the evaluation on fixed validation seeds
  (``coopnav_env.seeds.VALIDATION_SEED``) that picks the best model.

From Python:

    from agents.training import TrainConfig, train
    train(TrainConfig(scenario="gao_lawnmower", timesteps=4096, n_envs=4, ppo={"n_steps": 128}), "runs/x")

Exit status: 0 done, 2 bad input (one line on stderr, nothing written), 130 stopped
by Ctrl-C or SIGTERM after writing a checkpoint (``python train.py --resume DIR``
continues it to the same total step count).
"""

import sys

from agents.training.cli import main

if __name__ == "__main__":
    sys.exit(main())
