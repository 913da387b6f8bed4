"""Architecture rules of DESIGN.md, checked: the layer contracts of pyproject.toml
(import-linter, which sees imports inside functions too) and what no static analysis
can see."""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_the_layer_contracts_hold():
    """``lint-imports``: light layers free of torch, Qt, pyvista and matplotlib; render
    and plots never import the app; workbench never imports engines; engines never import
    the app, render, plots or each other."""
    tool = Path(sys.executable).with_name("lint-imports")
    out = subprocess.run([str(tool)], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]


def test_listing_engines_is_light():
    """Engine modules import torch inside fit and clean only, so listing them is fast."""
    code = (
        "import sys\nfrom workbench import registry\n[registry.get(n) for n in registry.available()]\n"
        "print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", "engine modules must import torch lazily"


def test_datasets_is_data_only():
    assert not (REPO / "datasets" / "__init__.py").exists()
