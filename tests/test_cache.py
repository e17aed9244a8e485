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
