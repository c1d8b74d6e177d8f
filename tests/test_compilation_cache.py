"""The per-user persistent compilation cache: on by default, opt-out, harmless when the home
folder cannot be written. Each case runs in a fresh process (the cache is process state)."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROBE = (
    "from brdffit import compilation_cache as c; folder = c.enable(); print(folder)\n"
    "import jax, jax.numpy as jnp\n"
    "jax.config.update('jax_persistent_cache_min_compile_time_secs', 0)\n"
    "print(float(jax.jit(lambda x: jnp.sin(x) * 2)(1.0)))\n"
    "print(jax.config.jax_compilation_cache_dir)\n"
)


def probe(tmp_path, **env):
    full = {k: v for k, v in os.environ.items()
            if k not in ("BRDFFIT_NO_COMPILATION_CACHE", "BRDFFIT_COMPILATION_CACHE_DIR")}
    full.update(PYTHONPATH=str(ROOT), **env)
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=tmp_path, env=full,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.split("\n")


def test_cache_goes_to_the_user_cache_folder_and_is_filled(tmp_path):
    folder, value, config = probe(tmp_path, XDG_CACHE_HOME=str(tmp_path / "xdg"))[:3]
    assert folder == str(tmp_path / "xdg" / "brdffit" / "jax") == config
    assert abs(float(value) - 1.682941969) < 1e-6
    assert any(p.name.endswith("-cache") for p in (tmp_path / "xdg" / "brdffit" / "jax").iterdir())


def test_opt_out_variable_keeps_the_cache_off(tmp_path):
    folder, _, config = probe(tmp_path, XDG_CACHE_HOME=str(tmp_path / "xdg"),
                              BRDFFIT_NO_COMPILATION_CACHE="1")[:3]
    assert folder == "None" and config in ("None", "")
    assert not (tmp_path / "xdg").exists()


def test_an_unwritable_home_disables_the_cache_and_the_cli_still_runs(tmp_path):
    blocked = tmp_path / "home-is-a-file"
    blocked.write_text("not a folder")  # mkdir under it fails, as in a read-only home
    env = {"HOME": str(blocked), "XDG_CACHE_HOME": str(blocked / ".cache")}
    folder, value, _ = probe(tmp_path, **env)[:3]
    assert folder == "None" and abs(float(value) - 1.682941969) < 1e-6
    full = {**{k: v for k, v in os.environ.items() if k != "BRDFFIT_COMPILATION_CACHE_DIR"},
            "PYTHONPATH": str(ROOT), **env}
    out = subprocess.run([sys.executable, str(ROOT / "cli.py"), "synth", "--model", "ggx",
                          "--samples", "20", "-o", "s.csv", "--quiet"], cwd=tmp_path, env=full,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert (tmp_path / "s.csv").is_file()
