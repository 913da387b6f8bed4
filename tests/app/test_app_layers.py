"""DESIGN.md's layers for the app: ``render`` and ``plots`` import neither ``app`` nor
Qt; ``app.take`` and ``app.report`` (shared with the headless report) import no Qt."""

import subprocess
import sys


def imported(modules: list[str]) -> set[str]:
    code = "import sys\n" + "".join(f"import {m}\n" for m in modules) + "print(' '.join(sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_render_and_plots_import_neither_app_nor_qt():
    loaded = imported(["workbench.render", "workbench.render.scene", "workbench.plots"])
    assert not {m for m in loaded if m.startswith(("workbench.app", "PySide6"))}


def test_the_headless_report_imports_no_qt():
    loaded = imported(["workbench.app.take", "workbench.app.report", "workbench.app.figures"])
    assert not {m for m in loaded if m.startswith("PySide6")}
