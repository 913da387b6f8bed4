"""Architecture rules of DESIGN.md, checked."""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LIGHT = ["workbench.core", "workbench.io", "workbench.data", "workbench.corruption", "workbench.metrics",
         "workbench.engine", "workbench.registry", "workbench.evaluate", "workbench.cli"]


def test_core_layers_do_not_import_heavy_libraries():
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in LIGHT)
        + "from workbench import registry\nregistry.available()\n"
        + "heavy = [m for m in ('torch', 'pyvista', 'vtk', 'matplotlib', 'PySide6') if m in sys.modules]\n"
        + "print(','.join(heavy))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"light layers imported: {out.stdout.strip()}"


def test_listing_engines_is_light():
    code = ("import sys\nfrom workbench import registry\n"
            "[registry.get(n) for n in registry.available()]\n"
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", "engine modules must import torch lazily"


def test_datasets_is_data_only():
    assert not (REPO / "datasets" / "__init__.py").exists()


def test_workbench_never_imports_engines_by_name():
    for path in (REPO / "workbench").rglob("*.py"):
        text = path.read_text()
        assert "import engines" not in text and "from engines" not in text, path
