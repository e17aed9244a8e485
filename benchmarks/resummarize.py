"""Re-summarise a benchmark result under this checkout's rules, without running it again.

    python benchmarks/resummarize.py results/bench_gao_sea --out results/bench_gao_sea_v6

Reads ``RESULTS_DIR/results.json`` (``python -m evaluation.benchmark``'s output), recomputes
every task's headroom and each task set's pooled headroom from the per-episode errors it
holds (``evaluation.benchmark.resummarize``: benchmark v6 counts a headroom only where its
paired interval lies above 0), and writes results.json and results.md to ``--out`` (a new
directory, or ``--overwrite``); ``resummarized`` in results.json says which rules were
applied. The runs themselves (errors, verdicts, costs) are kept as they were.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Sequence

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def main(argv: Sequence[str] | None = None) -> int:
    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("results_dir", help="a benchmark output directory (holds results.json)")
    p.add_argument("--out", required=True, help="where to write the re-summarised results.json and results.md")
    p.add_argument("--overwrite", action="store_true", help="replace a result already in --out")
    p.add_argument("--no-figures", action="store_true", help="write no benchmark_<set>.png")
    args = p.parse_args(argv)
    src = os.path.join(args.results_dir, "results.json")
    try:
        with open(src) as f:
            results = json.load(f)
        problem = _args.benchmark_results_problem(results)
        if problem is not None:
            raise ValueError(problem)
    except (OSError, ValueError) as err:
        p.error(f"{src}: not a benchmark result ({_args.first_line(err)})")
    if os.path.abspath(args.out) == os.path.abspath(args.results_dir):
        p.error("--out must differ from RESULTS_DIR (the run stays as it was)")
    from evaluation.benchmark import check_out_folder, resummarize, write_results
    from evaluation.errors import UsageError

    try:  # the benchmark's own check of its --out: not a file, no evaluate.py result, writable
        check_out_folder(args.out, args.overwrite)
    except UsageError as err:
        p.error(str(err))

    files = write_results(args.out, resummarize(results), figures=not args.no_figures)
    print(f"wrote {args.out}/: {', '.join(os.path.basename(f) for f in files)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
