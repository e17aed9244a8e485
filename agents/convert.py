"""Convert a trusted pickle-based policy or run directory to the safe format.

    python -m agents.convert runs/old_run --out runs/old_run_safe --trust-pickle
    python -m agents.convert downloaded/model.zip --out policies/mine --trust-pickle
    python -m agents.convert runs/x_rllib --out runs/x_rllib_safe --trust-pickle   # an RLlib run

Reading the old formats (an SB3 model ``.zip``, a VecNormalize ``.pkl``, an RLlib
checkpoint) unpickles them, which runs whatever code they hold: do it only for files
you trust (you trained them, or they come from someone you trust), hence the
required ``--trust-pickle``. The converted directory holds data only
(``agents.formats``: safetensors + JSON) and loads everywhere without the flag.

An SB3 run directory: ``model.zip`` + ``vecnormalize.pkl`` -> ``model.safetensors`` +
``vecnormalize.safetensors``, the same for ``best_*`` and every checkpoint (its
``last_checkpoint.json`` rewritten); config.yml and the other plain files are copied;
subdirectories (a gated policy's networks) are converted the same way. A lone
``.zip`` becomes ``NEW_DIR/model.safetensors`` (with the ``.pkl`` beside it, if any,
and the ``config.yml`` of its directory). An RLlib run or checkpoint becomes a copy
of its directory plus the safe export ``agents.rllib_policy`` reads
(``policy_export/``), if this build supports it.

Exit status: 0 converted; 2 bad input or refused (one line on stderr).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from coopnav_env.failures import MACHINE_FAILURES, one_line
from coopnav_env.records import atomic_write_bytes, atomic_write_text

from . import formats, safe_paths
from .formats import PolicyFormatError


def _read_json(path):
    from coopnav_env.safe_load import read_json

    return read_json(path)  # bounded; an UnsafeDataError (a ValueError) names the file


PICKLE_SUFFIXES = formats.PICKLE_SUFFIXES
PAIRS = (("best_model.zip", "best_vecnormalize.pkl"), ("model.zip", "vecnormalize.pkl"))

__all__ = ["convert", "convert_model", "main"]


def convert_model(
    zip_path: str | Path,
    pkl_path: str | Path | None,
    out_model: str | Path,
    out_stats: str | Path,
    norm_obs_hint: bool | None = None,
) -> dict:
    """Convert one trusted (model .zip, VecNormalize .pkl or None) pair; returns the spec."""
    stats = formats.legacy_vecnormalize(pkl_path) if pkl_path is not None and Path(pkl_path).is_file() else None
    norm_obs = stats["norm_obs"] if stats is not None else norm_obs_hint
    model = formats.legacy_model(zip_path)
    formats.save_model(model, out_model, norm_obs=norm_obs)
    if stats is not None:
        formats.save_vecnormalize(stats, out_stats)
    return formats.model_spec(model, norm_obs)


def _convert_dir(src: Path, out: Path, written: list):
    out.mkdir(parents=True, exist_ok=True)
    converted = set()
    for zip_name, pkl_name in PAIRS:
        if (src / zip_name).is_file():
            stem = zip_name[:-4]
            convert_model(
                src / zip_name, src / pkl_name, out / f"{stem}.safetensors", out / f"{pkl_name[:-4]}.safetensors"
            )
            converted |= {zip_name, pkl_name}
            written.append(out / f"{stem}.safetensors")
    ckpt = src / "checkpoints"
    if ckpt.is_dir():
        (out / "checkpoints").mkdir(exist_ok=True)
        for z in sorted(ckpt.glob("ckpt_*.zip")):
            stem = z.name[:-4]
            convert_model(
                z,
                ckpt / f"{stem}_vecnormalize.pkl",
                out / "checkpoints" / f"{stem}.safetensors",
                out / "checkpoints" / f"{stem}_vecnormalize.safetensors",
            )
            written.append(out / "checkpoints" / f"{stem}.safetensors")
        last = ckpt / "last_checkpoint.json"
        if last.is_file():
            info = _read_json(last)
            for key in ("model", "vecnormalize"):
                formats.check_inside(ckpt, str(info[key]), f"{last}: file")
                name = str(info[key])
                for old, new in ((".zip", ".safetensors"), (".pkl", ".safetensors")):
                    if name.endswith(old):
                        name = name[: -len(old)] + new
                info[key] = name
            if not (out / "checkpoints" / info["model"]).is_file():
                raise PolicyFormatError(f"{last} names {info['model']}, which was not converted")
            atomic_write_text(out / "checkpoints" / "last_checkpoint.json", json.dumps(info))
        for f in ckpt.iterdir():
            if f.is_file() and f.suffix not in PICKLE_SUFFIXES and f.name != "last_checkpoint.json":
                atomic_write_bytes(out / "checkpoints" / f.name, f.read_bytes())
    for f in sorted(src.iterdir()):
        if f.name in converted or f.name == "checkpoints" or f.is_symlink():
            continue
        if f.is_dir():
            _convert_dir(f, out / f.name, written)
        elif f.suffix in PICKLE_SUFFIXES:
            print(f"note: skipped {f} (a pickle-based file this tool does not know)", file=sys.stderr)
        else:
            atomic_write_bytes(out / f.name, f.read_bytes())


def _already_safe(src: Path) -> bool:
    """``src`` is a safetensors model file, or a run or policy folder with a safetensors model
    and no pickle-based file anywhere in it (what ``train.py`` and the batched loop write)."""
    from . import rllib_policy
    from .batched_policy import WEIGHTS

    if src.is_file():
        return src.suffix == ".safetensors"
    if not src.is_dir() or rllib_policy.is_rllib_path(src):
        return False
    models = ("model.safetensors", "best_model.safetensors", WEIGHTS)
    if not any((src / name).is_file() for name in models):
        return False
    return not any(f.suffix in PICKLE_SUFFIXES for f in src.rglob("*") if f.is_file())


def convert(src: str | Path, out: str | Path, trust_pickle: bool = False) -> list:
    """Convert ``src`` (an old SB3 run or policy directory, a model .zip, or an RLlib
    run/checkpoint) into the new directory ``out``; returns the model files written.
    Refused (``PickleRefused``) without ``trust_pickle``."""
    from . import rllib_policy

    src, out = Path(src), Path(out)
    if not src.exists():
        raise PolicyFormatError(f"no such file or directory: {src}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise PolicyFormatError(f"--out {out} exists and is not an empty directory")
    if out.resolve() == src.resolve() or src.resolve() in out.resolve().parents:
        raise PolicyFormatError(f"--out {out} must lie outside {src}")
    # nothing outside the folder named is read or copied: no link in it may lead out
    if src.is_dir():
        safe_paths.check_tree(src)
    else:
        safe_paths.inside(src.parent, src.name, "model file")
    if _already_safe(src):
        raise PolicyFormatError(f"{src} is already in the safe format (safetensors): nothing to convert; load it as is")
    if not trust_pickle:
        formats.refuse_pickle(src, "read by unpickling (an SB3 .zip/.pkl or an RLlib checkpoint)")
    written: list = []
    if rllib_policy.is_rllib_path(src):
        rllib_policy.convert(src, out)
        return [out]
    if src.is_file():
        if src.suffix != ".zip":
            raise PolicyFormatError(f"{src}: expected an SB3 model .zip, a run directory or an RLlib checkpoint")
        stem = src.name[:-4]
        pkl = next(
            (
                c
                for c in (
                    src.with_name(stem + "_vecnormalize.pkl"),
                    src.with_name("best_vecnormalize.pkl" if stem == "best_model" else "vecnormalize.pkl"),
                )
                if c.is_file()
            ),
            None,
        )
        config = next((d / "config.yml" for d in (src.parent, src.parent.parent) if (d / "config.yml").is_file()), None)
        for extra in (pkl, config):
            if extra is not None:
                safe_paths.inside(extra.parent, extra.name, "file")
        out.mkdir(parents=True, exist_ok=True)
        convert_model(src, pkl, out / "model.safetensors", out / "vecnormalize.safetensors")
        if config is not None:
            atomic_write_bytes(out / "config.yml", config.read_bytes())
        return [out / "model.safetensors"]
    _convert_dir(src, out, written)
    if not written and not (out / "gate.yml").is_file():
        raise PolicyFormatError(f"{src} holds no SB3 model (model.zip, best_model.zip or checkpoints/ckpt_*.zip)")
    return written


def _discard(out: Path, existed: bool):
    """Empty ``out``, or remove it if it did not exist (it was absent or empty before
    this conversion started)."""
    import shutil

    if out.is_dir() and not out.is_symlink():
        for child in list(out.iterdir()):
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child, ignore_errors=True)
            else:
                child.unlink(missing_ok=True)
        if not existed:
            out.rmdir()


def main(argv: list[str] | None = None) -> int:
    name = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    prog = "coopnav-convert" if name.startswith("coopnav-convert") else "python -m agents.convert"  # as invoked
    p = argparse.ArgumentParser(
        prog=prog, description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "src", metavar="RUN_DIR_OR_ZIP", help="an old run or policy directory, a model .zip, or an RLlib run/checkpoint"
    )
    p.add_argument("--out", metavar="NEW_DIR", required=True, help="the converted directory (absent or empty)")
    p.add_argument(
        "--trust-pickle",
        action="store_true",
        help="you trust SRC: unpickling it runs whatever code it holds (required)",
    )
    args = p.parse_args(argv)
    out = Path(args.out)
    existed = out.exists() or out.is_symlink()
    fresh = not existed or (out.is_dir() and not any(out.iterdir()))
    refused: tuple[type[BaseException], ...] = (PolicyFormatError, ValueError, KeyError, *MACHINE_FAILURES)
    try:
        written = convert(args.src, args.out, trust_pickle=args.trust_pickle)
    except refused as err:
        if isinstance(err, MACHINE_FAILURES):
            text = one_line(err)
        else:
            text = " ".join(str(err).splitlines())
        if fresh:
            _discard(out, existed)  # no half-converted folder: --out is as it was (absent or empty)
        print(f"{prog}: error: {text}", file=sys.stderr)
        return 2
    print(f"converted {args.src} -> {args.out} ({len(written)} model file(s)); load it with agents.load({args.out!r})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
