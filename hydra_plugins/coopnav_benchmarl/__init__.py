"""Hydra plugin: coopnav's BenchMARL configs for ``python -m benchmarl.run``.

Hydra imports every module under the ``hydra_plugins`` namespace when an app composes
its config. This one adds ``configs/benchmarl`` (task/coopnav/*.yaml,
experiment/coopnav.yaml) to the search path and, when the app is BenchMARL's (its
``benchmarl.environments`` is loaded), registers the ``coopnav/<task set>`` tasks in
BenchMARL's registry (``agents.training.benchmarl_task.register``). Other Hydra apps get
the search-path entry only: nothing is imported for them.
"""
