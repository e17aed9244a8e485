"""The numba kernel cache follows edits anywhere in the core (coopnav_env.core._cache)."""

from coopnav_env.core import _cache


def test_stale_kernels_are_cleared_when_any_core_source_changes(tmp_path, monkeypatch):
    core = tmp_path / "core"
    (core / "__pycache__").mkdir(parents=True)
    (core / "a.py").write_text("x = 1\n")
    (core / "b.py").write_text("y = 2\n")
    kernel = core / "__pycache__" / "b.kernel-1.py311.nbi"
    monkeypatch.setattr(_cache, "CORE", core)
    monkeypatch.setattr(_cache, "STAMP", core / "__pycache__" / "numba-source.sha256")
    kernel.write_text("cached")
    assert _cache.clear_stale_kernels()  # no stamp yet: clear and stamp
    assert not kernel.exists()
    kernel.write_text("cached")
    assert not _cache.clear_stale_kernels()  # unchanged source: the cache stays
    assert kernel.exists()
    (core / "a.py").write_text("x = 3\n")  # a callee in another file changes
    assert _cache.clear_stale_kernels()
    assert not kernel.exists()


def test_threaded_twins_have_cache_files_of_their_own():
    """Each kernel compiled twice (serial, and parallel=True for large batches) must
    reach numba's cache under two names: the cache keys entries by module, qualified
    name, line, signature and bytecode, not by compile options (numba #6845), so twins
    of one function shared an entry and the first compiled was loaded for both."""
    import importlib
    import pkgutil

    from numba.core.registry import CPUDispatcher

    import coopnav_env.core as core

    twins, serial = [], {}
    for info in pkgutil.walk_packages(core.__path__, core.__name__ + "."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if isinstance(obj, CPUDispatcher) and obj.__module__ == module.__name__:
                if obj.targetoptions.get("parallel"):
                    twins.append(obj)
                else:
                    serial[obj.py_func.__code__] = obj
    assert len(twins) >= 10  # substeps (2), fusion (2), observation, channel, modem, mls, moving network (2)
    for twin in twins:
        name = twin.py_func.__qualname__
        assert name.endswith("_parallel"), f"{twin.__module__}.{name}: compile it with core.jit.parallel_twin"
        partner = serial.get(twin.py_func.__code__)
        assert partner is not None and partner.py_func.__qualname__ + "_parallel" == name
