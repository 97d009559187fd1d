"""The command line's persistent compilation cache (jaxclear/cli/cache.py): where it goes, that
compiled programs are written there, and that it can be switched off."""

import argparse

import jax
import jax.numpy as jnp
import pytest
from jax.experimental.compilation_cache import compilation_cache

from jaxclear.cli import build_parser, cache
from jaxclear.integrate import programs


@pytest.fixture
def restore_cache_config():
    keys = ("jax_compilation_cache_dir", "jax_persistent_cache_min_compile_time_secs",
            "jax_persistent_cache_min_entry_size_bytes")
    saved = {k: getattr(jax.config, k) for k in keys}
    yield
    for k, v in saved.items():
        jax.config.update(k, v)
    compilation_cache.reset_cache()
    programs.enable(None)


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
