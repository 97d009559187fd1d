"""The command line's persistent compilation cache (jaxclear/cli/cache.py): where it goes, that
compiled programs are written there, and that it can be switched off."""

import argparse
import warnings

import jax
import jax.numpy as jnp
import pytest
from jax.experimental.compilation_cache import compilation_cache

from jaxclear import caches
from jaxclear.cli import build_parser, cache
from jaxclear.integrate import _programs as programs


@pytest.fixture
def restore_cache_config():
    """The session's caches (tests/conftest.py: a temporary folder) back after the test."""
    keys = ("jax_compilation_cache_dir", "jax_persistent_cache_min_compile_time_secs",
            "jax_persistent_cache_min_entry_size_bytes", "jax_compilation_cache_max_size")
    saved = {k: getattr(jax.config, k) for k in keys}
    folder, jax_set = caches.cache_folder(), caches._STATE["jax"]
    yield
    if folder is None:
        caches.disable_cache()
    else:
        caches.enable_cache(folder, compilation=jax_set)
    for k, v in saved.items():
        jax.config.update(k, v)
    compilation_cache.reset_cache()


def test_default_dir_from_environment(monkeypatch, tmp_path):
    monkeypatch.delenv(cache.ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache.default_dir() == tmp_path / "jaxclear" / "xla"
    monkeypatch.setenv(cache.ENV, str(tmp_path / "mine"))
    assert cache.default_dir() == tmp_path / "mine"
    for off in ("off", "0", "", "None"):
        monkeypatch.setenv(cache.ENV, off)
        assert cache.default_dir() is None


def test_cache_folder_used_and_switched_off(tmp_path, restore_cache_config):
    folder = tmp_path / "cache"
    args = build_parser().parse_args(["--cache-dir", str(folder), "presets"])
    assert cache.configure(args) == folder and cache.active()
    assert jax.config.jax_compilation_cache_dir == str(folder)
    assert programs.folder() == folder / cache.PROGRAMS  # traced programs kept beside the compiled ones
    assert not cache.progress_allowed(argparse.Namespace(no_progress=False))  # a callback is not cacheable
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # a tiny program, written anyway
    compilation_cache.reset_cache()
    jax.block_until_ready(jax.jit(lambda x: jnp.sin(x) * 3.0 + 0.123456)(jnp.arange(7.0)))
    assert any(p.name.endswith("-cache") for p in folder.iterdir())

    jax.config.update("jax_compilation_cache_dir", None)
    off = build_parser().parse_args(["--no-cache", "--cache-dir", str(tmp_path / "other"), "presets"])
    assert cache.configure(off) is None and not cache.active() and programs.folder() is None
    assert not (tmp_path / "other").exists()
    assert cache.progress_allowed(argparse.Namespace(no_progress=False))


# ---- the same caches from the Python API (jaxclear/integrate/caches.py) ------------------------------------


def test_api_enables_both_stores_and_switches_them_off(tmp_path, restore_cache_config):
    import jaxclear as jc

    folder = tmp_path / "api"
    assert jc.enable_cache(folder, max_mb=8) == folder == jc.cache_folder()
    assert jax.config.jax_compilation_cache_dir == str(folder)
    assert jax.config.jax_compilation_cache_max_size == 6_000_000  # 3/4 of the limit; 1/4 for traced programs
    assert jax.config.jax_persistent_cache_min_compile_time_secs == caches.MIN_COMPILE_TIME_S
    assert programs.folder() == folder / caches.PROGRAMS
    jc.disable_cache()
    assert jc.cache_folder() is None and programs.folder() is None and not jax.config.jax_compilation_cache_dir


def test_default_folder_and_opt_out_at_import(monkeypatch, tmp_path, restore_cache_config):
    caches.disable_cache()
    assert not jax.config.jax_compilation_cache_dir
    monkeypatch.setenv(caches.ENV, "off")
    assert caches.enable_at_import() is None and caches.cache_folder() is None and programs.folder() is None
    monkeypatch.setenv(caches.ENV, str(tmp_path / "env"))
    assert caches.enable_at_import() == tmp_path / "env" and jax.config.jax_compilation_cache_dir == str(tmp_path / "env")
    # a JAX cache the user configured before importing jaxclear is left alone: traced programs only
    caches.disable_cache()
    jax.config.update("jax_compilation_cache_dir", str(tmp_path / "mine"))
    assert caches.enable_at_import() == tmp_path / "env"
    assert jax.config.jax_compilation_cache_dir == str(tmp_path / "mine") and programs.folder() is not None
    caches.disable_cache()
    assert jax.config.jax_compilation_cache_dir == str(tmp_path / "mine")  # still the user's
    monkeypatch.setenv(caches.SIZE_ENV, "12.5")
    assert caches.max_megabytes() == 12.5
    monkeypatch.setenv(caches.SIZE_ENV, "lots")
    with pytest.warns(UserWarning, match="JAXCLEAR_CACHE_MAX_MB='lots' is not a number"):
        assert caches.max_megabytes() == caches.DEFAULT_MAX_MB
    monkeypatch.delenv(caches.SIZE_ENV)


def test_unwritable_folder_leaves_the_api_caches_off_with_a_warning(tmp_path, restore_cache_config):
    (tmp_path / "file").write_text("not a folder")
    with pytest.warns(UserWarning, match="is a file, not a folder; going on without the compilation cache"):
        assert caches.enable_cache(tmp_path / "file") is None
    assert caches.cache_folder() is None and programs.folder() is None


def test_clear_cache_removes_only_cache_files(tmp_path):
    folder = tmp_path / "c"
    (folder / caches.PROGRAMS).mkdir(parents=True)
    for name in ("jit_f-abc-cache", "jit_f-abc-atime", f"{caches.PROGRAMS}/k{programs.SUFFIX}"):
        (folder / name).write_bytes(b"x")
    (folder / "notes.txt").write_text("mine")
    assert caches.clear_cache(folder) == 3
    assert sorted(p.name for p in folder.rglob("*")) == ["notes.txt", caches.PROGRAMS]


def test_traced_programs_keep_under_their_size_limit(tmp_path):
    import os

    folder = tmp_path / "p"
    folder.mkdir()
    for i in range(4):  # 4 programs of 100 bytes, used in this order (oldest first)
        path = folder / f"k{i}{programs.SUFFIX}"
        path.write_bytes(b"x" * 100)
        os.utime(path, ns=(i * 10**9, i * 10**9))
    (folder / "other.txt").write_bytes(b"y" * 1000)  # not a program: never counted or removed
    programs._evict(folder, 250)
    assert sorted(p.name for p in folder.iterdir()) == ["k2.jaxexport", "k3.jaxexport", "other.txt"]
    programs._evict(folder, None)  # no limit: nothing removed
    assert len(list(folder.iterdir())) == 3


def test_entries_written_without_a_limit_get_their_access_times(tmp_path, restore_cache_config):
    """A folder filled by JAX without a size limit has no ``-atime`` files; JAX's eviction needs
    them, so jaxclear adds them when it sets the limit (else no program would be written)."""
    folder = tmp_path / "old"
    folder.mkdir()
    (folder / "jit_g-123-cache").write_bytes(b"z")
    caches.enable_cache(folder)
    assert (folder / "jit_g-123-atime").stat().st_size == 8
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    compilation_cache.reset_cache()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        jax.block_until_ready(jax.jit(lambda x: jnp.cos(x) * 5.0 + 0.654321)(jnp.arange(9.0)))
    assert not [w for w in said if "compilation cache" in str(w.message)], [str(w.message) for w in said]
    assert len(list(folder.glob("jit__lambda-*-cache"))) == 1 and (folder / "jit_g-123-cache").exists()
