"""MkDocs hook: the reference pages that are generated from the code at build time.

Declared in ``mkdocs.yml`` (``hooks: [docs/hooks/generate.py]``). Nothing is written
into the source tree: the pages are added to the build's file list with
``File.generated`` in ``on_files``.

* ``reference/parameters.md``: one table per section of
  ``coopnav_env.scenarios.base.ScenarioConfig`` (``scenarios/sections.py``): every
  parameter with its type, default, unit, range, meaning and source, all from its
  ``param(...)`` metadata; then which registered scenario overrides which parameter
  (``make_config(name)`` against the defaults), with the scenario files' source.
* ``reference/scenarios.md``: every registered scenario (``list_scenarios()``), the
  sections that apply to it and its values that differ from the defaults.
* ``reference/observations.md``: the observation layouts. The survey network's
  from the layout table in ``coopnav_env.core.observation``'s docstring (or an
  ``OBS_FIELDS`` there, if one appears) and its constants; the moving network's
  from ``coopnav_env.core.moving_network.OBS_FIELDS``; the length of each
  scenario's observation from ``coopnav_env.obs_layout.obs_dim``.

* In any page, a line ``<!-- generated: REWARD_TERMS -->`` or ``<!-- generated:
  TRAINING_SIGNALS -->`` becomes the table of the registered reward terms or training
  signals (``coopnav_env.core.reward.markdown_table``), and a line
  ``<!-- generated: NAME -->`` the table of ``evaluation.report.NAME``
  (``EPISODE_COLUMN_DOCS``, ``STEP_COLUMN_DOCS``, ``SUMMARY_COLUMNS``,
  ``FRAME_COLUMNS``): every column of the evaluation's outputs with
  its unit, from the dicts the CSV headers and summary.md are written from. A failure is a
  warning, which ``mkdocs build --strict`` turns into an error.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import logging
import re
import sys
import textwrap
from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files
from mkdocs.structure.pages import Page

log = logging.getLogger("mkdocs.hooks.generate")

ROOT = Path(__file__).resolve().parents[2]  # the repository (docs/hooks/generate.py)
if str(ROOT) not in sys.path:  # the project's packages, installed or not
    sys.path.insert(0, str(ROOT))


def unit_of(name: str) -> str:
    """A parameter's unit, from its ``param(unit=...)`` metadata ("-" when dimensionless)."""
    from coopnav_env.scenarios.config import FIELD

    return FIELD[name].metadata["unit"] if name in FIELD else "-"


# ------------------------------------------------------------------------------------
# markdown helpers


def _cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _code(value) -> str:
    r = repr(value)
    return "`" + r.replace("|", "\\|") + "`"


def _table(head, rows) -> str:
    out = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    out += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def _anchor(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


# ------------------------------------------------------------------------------------
# reference/parameters.md


def _scenario_sources() -> dict:
    """{scenario name: (file, source)}: the ``NAME = ScenarioConfig(name=..., ...)`` statement
    of each scenario in coopnav_env/scenarios/*.py, verbatim with its comments."""
    out = {}
    for path in sorted((ROOT / "coopnav_env" / "scenarios").glob("*.py")):
        source = path.read_text()
        lines = source.splitlines()
        for node in ast.parse(source).body:
            call = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
            if not (
                isinstance(call, ast.Call)
                and getattr(call.func, "id", getattr(call.func, "attr", None)) == "ScenarioConfig"
            ):
                continue
            kw = {k.arg: k.value for k in call.keywords if k.arg}
            name = kw.get("name")
            if isinstance(name, ast.Constant):
                text = "\n".join(lines[node.lineno - 1 : node.end_lineno])
                out[name.value] = (path.relative_to(ROOT).as_posix(), text)
    return out


def _applies_text(spec) -> str:
    return " and ".join(f"`{k}={v!r}`" for k, v in spec.requires) or "always"


def parameters_page() -> str:
    import coopnav_env
    from coopnav_env.scenarios.base import SECTIONS, ScenarioConfig, range_text

    defaults = ScenarioConfig()
    n_params = sum(len(dataclasses.fields(s.cls)) for s in SECTIONS)
    out = [
        "# Scenario parameters",
        "",
        '!!! info "Generated from the code"',
        "    This page is generated at build time (`docs/hooks/generate.py`) from the sections of",
        "    `coopnav_env.scenarios.base.ScenarioConfig` (`coopnav_env/scenarios/sections.py`): each",
        "    parameter's default, unit, range, meaning and source are declared there with",
        "    `param(...)`, and the same metadata validates every value. Edit them there, not here.",
        "",
        "Every parameter is a keyword of `coopnav_env.parallel_env(...)`, `coopnav_env.make_config(...)`,",
        "`evaluate.py --set KEY=VALUE` / `--sweep KEY=V1,V2` and the training YAML's `env.overrides`,",
        "flat (`ping_interval_s=10`) or with its section (`timing.ping_interval_s=10`). Names are unique",
        "across sections, and `config.ping_interval_s` reads `config.timing.ping_interval_s`.",
        "A section that does not apply to a scenario is `None` (the *applies* column below); setting",
        "one of its parameters is an error that names the setting that enables it. `[U]` marks a",
        'value the sources do not give (an assumption); "ref-values section N" and "reference-values.md',
        '§N" cite `shared/reference-values.md`. A range `(0, x]` excludes 0.',
        "",
        f"{n_params} parameters in {len(SECTIONS)} sections, plus `name` (the scenario's name) and `network`",
        '(the simulator: `"survey_beacons"` or `"moving_lbl"`). Which sections and values each',
        "registered scenario has: [Scenarios](scenarios.md); [overrides by scenario](#overrides-by-scenario)",
        "follows the sections.",
        "",
        _table(
            ["section", "class", "applies", "parameters"],
            [
                [
                    f"[`{s.attr}`](#{s.attr})",
                    f"`{s.cls.__name__}`",
                    _applies_text(s),
                    str(len(dataclasses.fields(s.cls))),
                ]
                for s in SECTIONS
            ],
        ),
        "",
    ]
    from coopnav_env.scenarios.sections import NETWORKS

    out += [
        "## Top level {#top-level}",
        "",
        "Two fields outside the sections: the scenario's name and the simulator that reads it.",
        "",
        _table(
            ["parameter", "type", "default", "unit", "range", "meaning", "source"],
            [
                [
                    '<a id="name"></a>`name`',
                    "str",
                    _code(defaults.name),
                    "-",
                    "—",
                    "the scenario's name (make_config sets it)",
                    "—",
                ],
                [
                    '<a id="network"></a>`network`',
                    "str",
                    _code(defaults.network),
                    "-",
                    ", ".join(f"`{n!r}`" for n in NETWORKS),
                    "which simulator: survey vehicles in a fixed navigation frame with beacons that ping them "
                    "(Gao & Chitre, Sousa et al.), or one AUV in the frame of two beacon boats (Matos & Cruz)",
                    "—",
                ],
            ],
        ),
        "",
    ]
    for spec in SECTIONS:
        doc = " ".join(textwrap.dedent(spec.cls.__doc__ or "").split())
        out += [
            f"## `{spec.attr}`: {spec.cls.__name__} {{#{spec.attr}}}",
            "",
            doc,
            "",
            f"Applies: {_applies_text(spec)}.",
            "",
        ]
        rows = []
        for f in dataclasses.fields(spec.cls):
            m = f.metadata
            choices = ", ".join(f"`{c!r}`" for c in m["choices"]) if m.get("choices") else ""
            rows.append(
                [
                    f'<a id="{f.name}"></a>`{f.name}`',
                    type(f.default).__name__,
                    _code(f.default),
                    m["unit"],
                    range_text(f) or choices or "—",
                    m["doc"],
                    m["source"] or "—",
                ]
            )
        out += [_table(["parameter", "type", "default", "unit", "range", "meaning", "source"], rows), ""]

    # which scenario overrides what
    names = coopnav_env.list_scenarios()
    configs = {n: coopnav_env.make_config(n) for n in names}
    flat_default = defaults.to_flat_dict(all_parameters=True)
    changed = [
        p
        for p in flat_default
        if p != "name" and any(configs[n].applies(p) and getattr(configs[n], p) != flat_default[p] for n in names)
    ]
    out += [
        "## Overrides by scenario {#overrides-by-scenario}",
        "",
        "Each registered scenario (`coopnav_env.list_scenarios()`) against the defaults above:",
        "a value where `coopnav_env.make_config(name)` differs from the default, blank where it",
        'keeps it, "n/a" where the parameter\'s section does not apply. Parameters no scenario',
        "changes are not listed.",
        "",
    ]
    rows = []
    for p in changed:
        row = [f"[`{p}`](#{p})", unit_of(p), _code(flat_default[p])]
        for n in names:
            if not configs[n].applies(p):
                row.append("n/a")
                continue
            v = getattr(configs[n], p)
            row.append(_code(v) if v != flat_default[p] else "")
        rows.append(row)
    out += [_table(["parameter", "unit", "default"] + [f"`{n}`" for n in names], rows), ""]

    # the scenario files themselves
    sources = _scenario_sources()
    out += [
        "### The scenario files",
        "",
        "Each scenario's definition as written, with the comments that say where each value",
        "comes from (a keyword may restate a default).",
        "",
    ]
    for n in names:
        if n in sources:
            path, text = sources[n]
            out += [f'??? note "`{n}`: `{path}`"', "", "    ```python"]
            out += ["    " + line if line else "" for line in text.splitlines()]
            out += ["    ```", ""]
    return "\n".join(out)


# ------------------------------------------------------------------------------------
# reference/scenarios.md


def scenarios_page() -> str:
    """Every registered scenario: its sections and the values that differ from the defaults."""
    import coopnav_env
    from coopnav_env.scenarios.base import SECTIONS, ScenarioConfig

    flat_default = ScenarioConfig().to_flat_dict(all_parameters=True)
    names = coopnav_env.list_scenarios()
    configs = {n: coopnav_env.make_config(n) for n in names}
    out = [
        "# Scenarios",
        "",
        '!!! info "Generated from the registry"',
        "    This page is generated at build time (`docs/hooks/generate.py`) from",
        "    `coopnav_env.list_scenarios()` and `coopnav_env.make_config(name)`: a scenario registered",
        "    in `coopnav_env/scenarios/` appears here without further work.",
        "",
        f"{len(names)} registered scenarios. For each: the network, the sections that apply (the others",
        "are `None`: their parameters cannot be set) and every value that differs from its",
        "[default](parameters.md).",
        "",
        _table(
            ["scenario", "network", "beacons", "sections that do not apply"],
            [
                [
                    f"[`{n}`](#{_anchor(n)})",
                    f"`{c.network}`",
                    _code(c.beacon_kinds),
                    ", ".join(f"`{s.attr}`" for s in SECTIONS if getattr(c, s.attr) is None) or "—",
                ]
                for n, c in configs.items()
            ],
        ),
        "",
    ]
    for n, c in configs.items():
        out += [
            f"## `{n}` {{#{_anchor(n)}}}",
            "",
            f"`network={c.network!r}`. Sections: "
            + ", ".join(f"[`{a}`](parameters.md#{a})" for a in c.sections())
            + ".",
            "",
        ]
        rows = []
        for a, part in c.sections().items():
            for f in dataclasses.fields(part):
                v = getattr(part, f.name)
                if v != flat_default[f.name]:
                    text = _code(v)
                    if len(text) > 120 and isinstance(v, tuple):
                        text = f"{len(v)} entries, from `{v[0]!r}` to `{v[-1]!r}`"
                    rows.append(
                        [
                            f"[`{f.name}`](parameters.md#{f.name})",
                            f"`{a}`",
                            text,
                            _code(flat_default[f.name]),
                            f.metadata["unit"],
                        ]
                    )
        out += [
            _table(["parameter", "section", "value", "default", "unit"], rows)
            if rows
            else "All parameters at their defaults.",
            "",
        ]
    return "\n".join(out)


# ------------------------------------------------------------------------------------
# reference/observations.md


def _rst_simple_table(doc: str) -> list:
    """Rows (label, size, meaning, indent) of the first reST simple table in ``doc``."""
    lines = textwrap.dedent(doc).splitlines()
    rules = [i for i, l in enumerate(lines) if re.fullmatch(r"\s*=+(\s+=+)+\s*", l)]
    if len(rules) < 2:
        return []
    rule = lines[rules[0]]
    spans = [m.span() for m in re.finditer(r"=+", rule)]
    rows = []
    for line in lines[rules[0] + 1 : rules[1]]:
        if not line.strip():
            continue
        label = line[: spans[1][0]].rstrip()
        size = line[spans[1][0] : spans[2][0]].strip() if len(spans) > 2 else line[spans[1][0] :].strip()
        meaning = line[spans[2][0] :].strip() if len(spans) > 2 else ""
        indent = len(label) - len(label.lstrip())
        rows.append((label.strip(), size, meaning, indent))
    return rows


def _size(text: str, K: int) -> int | None:
    t = text.replace(" ", "")
    if not t:
        return None
    m = re.fullmatch(r"(\d*)K", t)
    if m:
        return int(m.group(1) or 1) * K
    return int(t)


def observations_page() -> str:
    import coopnav_env
    from coopnav_env import obs_layout
    from coopnav_env.core import moving_network as mn
    from coopnav_env.core import observation as ob

    names = coopnav_env.list_scenarios()
    configs = {n: coopnav_env.make_config(n) for n in names}
    out = [
        "# Observation layout",
        "",
        '!!! info "Generated from the code"',
        "    This page is generated at build time (`docs/hooks/generate.py`) from",
        "    `coopnav_env.core.observation` (the survey network's layout table and constants),",
        "    `coopnav_env.core.moving_network.OBS_FIELDS` (the moving network's boats) and",
        "    `coopnav_env.obs_layout.obs_dim`. Policies and tools never index the vector by hand:",
        "    `coopnav_env.obs_layout.decode(obs, config)` and `decode_boat(obs, config)` read it.",
        "",
        f"Every observation is a `Box(-{ob.OBS_BOUND:g}, {ob.OBS_BOUND:g}, (D,), float32)` per agent "
        f"(values clipped to ±`OBS_BOUND` = {ob.OBS_BOUND:g}), holding only what that agent could know.",
        "",
        "## Length by scenario",
        "",
    ]
    rows = []
    for n, c in configs.items():
        rows.append(
            [
                f"`{n}`",
                f"`{c.network}`",
                c.n_survey if c.network != "moving_lbl" else "1",
                c.n_beacons,
                c.observed_waypoints if c.network != "moving_lbl" else "—",
                obs_layout.obs_dim(c),
            ]
        )
    out += [_table(["scenario", "network", "survey vehicles S", "beacons N", "observed waypoints K", "D"], rows), ""]

    # survey network
    out += [
        '## Survey network (`network="survey_beacons"`)',
        "",
        "One beacon's vector, in this order. Positions are divided by "
        "L = `config.position_scale_m` (half the survey area's larger side plus the geofence margin); "
        "T is `ping_interval_s`.",
        "",
    ]
    fields = getattr(ob, "OBS_FIELDS", None)
    rows = []
    per_survey: list[tuple[str, str]] = []
    per_beacon: list[tuple[str, str]] = []
    if fields:  # a declared field list, if the code grows one
        for f in fields:
            name, size = f[0], f[1]
            meaning = f[2] if len(f) > 2 else ""
            rows.append([f"`{name}`", size, meaning])
        out += [_table(["field", "size", "meaning"], rows), ""]
    else:
        table = _rst_simple_table(ob.__doc__ or "")
        if not table:
            log.warning("generate.py: no layout table found in coopnav_env.core.observation's docstring")
        group = "own"
        for label, size, meaning, indent in table:
            if not size and label.endswith(":"):
                group = "survey"
                rows.append([f"**{label.rstrip(':')}** (repeated S times)", "", ""])
                continue
            if indent == 0:
                group = "beacon" if label.startswith("per other beacon") else "own"
            rows.append([("&nbsp;&nbsp;&nbsp;&nbsp;" if indent else "") + label, size, meaning])
            (per_survey if group == "survey" else per_beacon if group == "beacon" else []).append((label, size))
        out += [
            _table(["field", "size", "meaning"], rows),
            "",
            "`per other beacon` is repeated N - 1 times (the other beacons, in agent order).",
            "",
        ]
        # check the table against the code's dimension
        for n, c in configs.items():
            if c.network != "survey_beacons":
                continue
            K = c.observed_waypoints
            own = sum(_size(s, K) or 0 for l, s, m, i in table if i == 0 and not l.startswith("per other"))
            surv = sum(_size(s, K) or 0 for l, s in per_survey)
            beac = sum(_size(s, K) or 0 for l, s in per_beacon)
            total = own + c.n_survey * surv + (c.n_beacons - 1) * beac
            if total != obs_layout.obs_dim(c):
                log.warning(
                    f"generate.py: the layout table of coopnav_env.core.observation sums to {total} for "
                    f"{n}, but obs_layout.obs_dim gives {obs_layout.obs_dim(c)}"
                )
    consts = [
        (k, getattr(ob, k))
        for k in (
            "OWN_DIM",
            "PER_SURVEY_FIXED",
            "DEPTH_SCALE_M",
            "ELLIPSE_SCALE_M",
            "STD_SCALE_M",
            "AGE_SCALE_PINGS",
            "OBS_BOUND",
            "ELLIPSE_N_SIGMA",
        )
        if hasattr(ob, k)
    ]
    out += [
        "The layout's constants (`coopnav_env.core.observation`):",
        "",
        _table(["constant", "value"], [[f"`{k}`", _code(v)] for k, v in consts]),
        "",
        "D = `OWN_DIM` + S (`PER_SURVEY_FIXED` + 2K) + 2 (N - 1) (`coopnav_env.core.observation.obs_dim`).",
        "",
    ]
    # indices for one example
    ex = (
        "gao_lawnmower"
        if "gao_lawnmower" in configs
        else next(n for n, c in configs.items() if c.network == "survey_beacons")
    )
    c = configs[ex]
    K, S, N = c.observed_waypoints, c.n_survey, c.n_beacons
    idx, rows = 0, []
    table = _rst_simple_table(ob.__doc__ or "") if not fields else []
    own_rows = [(l, _size(sz, K) or 0) for l, sz, m, i in table if i == 0 and sz and not l.startswith("per other")]
    for l, n in own_rows:
        rows.append([l, f"{idx}:{idx + n}"])
        idx += n
    for s in range(S):
        for l, sz in per_survey:
            n = _size(sz, K) or 0  # a row without a size (as in the sums above) takes no slice
            rows.append([f"survey {s}: {l}", f"{idx}:{idx + n}"])
            idx += n
    for j in range(N - 1):
        for l, sz in per_beacon:
            n = _size(sz, K) or 0  # a row without a size (as in the sums above) takes no slice
            rows.append([f"other beacon {j}: {l}", f"{idx}:{idx + n}"])
            idx += n
    if rows:
        out += [
            f"Example: `{ex}` (S = {S}, N = {N}, K = {K}, D = {obs_layout.obs_dim(c)}), slices of the vector:",
            "",
            _table(["field", "slice"], rows),
            "",
        ]

    # moving network
    out += [
        '## Moving LBL network (`network="moving_lbl"`)',
        "",
        f"One boat's vector (`coopnav_env.core.moving_network.OBS_FIELDS`, `OBS_DIM` = {mn.OBS_DIM}), in this order:",
        "",
    ]
    rows, idx = [], 0
    with_meaning = any(len(f) > 2 for f in mn.OBS_FIELDS)  # (name, size[, meaning])
    for f in mn.OBS_FIELDS:
        name, n = f[0], f[1]
        rows.append([f"`{name}`", n, f"{idx}:{idx + n}"] + ([f[2] if len(f) > 2 else "—"] if with_meaning else []))
        idx += n
    out += [_table(["field", "size", "slice"] + (["meaning"] if with_meaning else []), rows), ""]
    doc = inspect.getdoc(mn.MovingNetworkSimulator.observe) or ""
    if doc:
        out += ["What the code says of these fields (the docstring of `MovingNetworkSimulator.observe`):", ""]
        out += ["> " + line if line else ">" for line in doc.splitlines()]
        out += [""]
    return "\n".join(out)


# ------------------------------------------------------------------------------------
# evaluation.md: the column tables, from evaluation.report

GENERATED_RE = re.compile(r"^<!-- generated: ([A-Z_]+) -->$", re.M)


def column_table(name: str) -> str:
    """The Markdown table of ``evaluation.report.<name>``: a dict column -> (unit, meaning)
    (``*_COLUMN_DOCS``) or summary key -> (summary.md header, format, unit, meaning)."""
    if name in ("REWARD_TERMS", "TRAINING_SIGNALS"):  # the reward registry's tables (coopnav_env.core.reward)
        from coopnav_env.core.reward import markdown_table

        return markdown_table("env" if name == "REWARD_TERMS" else "training")
    from evaluation import report

    docs = getattr(report, name)
    rows, four = [], False
    for key, value in docs.items():
        if len(value) == 4:
            four = True
            header, _fmt, unit, meaning = value
            rows.append([header, f"`{key}`", unit or "-", meaning])
        else:
            unit, meaning = value
            rows.append([f"`{key}`", unit or "-", meaning])
    if four:
        extra = getattr(report, "SUMMARY_COLUMN_DOCS", {})
        if name == "SUMMARY_COLUMNS":  # summary.json keys that summary.md's per-policy table does not show
            shown = set(docs) | set(getattr(report, "FRAME_COLUMNS", {}))
            rows += [["-", f"`{k}`", u or "-", m] for k, (u, m) in extra.items() if k not in shown]
        return _table(["summary.md column", "summary.json key", "unit", "definition"], rows)
    return _table(["column", "unit", "definition"], rows)


# ------------------------------------------------------------------------------------
# MkDocs events


def on_files(files: Files, config: MkDocsConfig) -> Files:
    for uri, make in (
        ("reference/parameters.md", parameters_page),
        ("reference/scenarios.md", scenarios_page),
        ("reference/observations.md", observations_page),
    ):
        files.append(File.generated(config, uri, content=make()))
    return files


def on_page_markdown(markdown: str, page: Page, config: MkDocsConfig, files: Files) -> str:
    def replace(m: re.Match[str]) -> str:
        try:
            return column_table(m.group(1))
        except Exception as err:  # any failure is a documentation error
            log.warning(
                f"generate.py: {page.file.src_uri}: cannot generate {m.group(1)} from evaluation.report: {err!r}"
            )
            return m.group(0)

    return GENERATED_RE.sub(replace, markdown)
