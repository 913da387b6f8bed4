"""The plugin story: a third-party engine package (tests/plugin_engine, its own
pyproject.toml) installs, registers through the ``mocap_workbench.engines`` entry point
and passes the whole conformance suite, built from the public workbench API alone."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

PLUGIN = Path(__file__).resolve().parent / "plugin_engine"


@pytest.mark.slow
def test_a_third_party_engine_installs_registers_and_passes_the_conformance_suite(tmp_path, data_root):
    site = tmp_path / "site"
    install = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--target",
            str(site),
            str(PLUGIN),
        ],
        capture_output=True,
        text=True,
    )
    assert install.returncode == 0, install.stderr[-2000:]
    env = dict(os.environ, PYTHONPATH=str(site), WORKBENCH_DATA=str(data_root), OMP_NUM_THREADS="1")
    alone = ["-c", str(PLUGIN / "pyproject.toml"), "--rootdir", str(PLUGIN), "--confcutdir", str(PLUGIN)]
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rs", *alone, str(PLUGIN / "tests")],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert " passed" in run.stdout and "failed" not in run.stdout
