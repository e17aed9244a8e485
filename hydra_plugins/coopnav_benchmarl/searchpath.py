"""The search-path plugin (see the package docstring)."""

from __future__ import annotations

import sys
from pathlib import Path

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs" / "benchmarl"


class CoopNavSearchPathPlugin(SearchPathPlugin):
    """Appends ``configs/benchmarl`` to Hydra's search path; registers the coopnav tasks in
    BenchMARL when BenchMARL is the app."""

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        if CONFIG_DIR.is_dir():
            search_path.append(provider="coopnav", path=f"file://{CONFIG_DIR}")
        if "benchmarl.environments" in sys.modules:
            from agents.training.benchmarl_task import register

            register()
