"""The Examples in the package's docstrings run, and say what they show (issue 59: the public API's
main entries carry an Examples section that runs in the suite)."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "handeye"
WITH_EXAMPLES = sorted(
    ".".join(("handeye",) + p.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__")
    for p in SRC.rglob("*.py") if ">>> " in p.read_text(encoding="utf-8"))
#: The public face's main entries: each has an Examples section.
MAIN_ENTRIES = ["calibrate", "calibrate_poses", "calibrate_joints", "calibrate_streams", "check_folder", "diagnose",
                "load_result", "parse_poses", "relative_motions", "solve", "write_calibration"]


@pytest.mark.slow
@pytest.mark.parametrize("name", WITH_EXAMPLES)
def test_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an example that writes files writes them here
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"


@pytest.mark.parametrize("entry", MAIN_ENTRIES)
def test_main_entries_have_examples(entry):
    import handeye

    doc = getattr(handeye, entry).__doc__ or ""
    assert "Examples\n" in doc and ">>> " in doc, entry
