"""The plugin passes the workbench's whole conformance suite, found through its entry point."""

import pytest

from workbench import registry
from workbench.testing import conformance_clips, parametrize_with_engine_checks, quick_untrained, run_check


@pytest.fixture(scope="module")
def takes():
    return conformance_clips(dataset="cmu")


def test_the_entry_point_registers_it():
    assert "median" in registry.available() and registry.get("median").__module__ == "workbench_median"


@parametrize_with_engine_checks(["median"])
def test_conformance(engine, check, takes):
    motion, foreign = takes
    run_check(
        check,
        lambda: registry.create(engine),
        motion,
        foreign=foreign,
        make_untrained=quick_untrained(engine),
        training=[motion],
    )
