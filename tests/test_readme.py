"""The README's examples run as written: its Python block, and the first four lines of its command
block (a rendered session, calibrated, checked, and a board to print); its links lead to files."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from handeye.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", README.read_text(), flags=re.S)


def test_the_python_example_runs_as_written():
    scope: dict = {}
    exec(compile(_blocks("python")[0], "README.md", "exec"), scope)  # noqa: S102 - our own README
    result = scope["result"]
    assert result.verdict == "good" and result.cam2flange.shape == (4, 4)
    assert np.allclose(scope["X"], result.X, atol=1e-3)  # the raw solve agrees with the calibration
    assert result.std.shape == (6,) and np.all(np.isfinite(result.std))


@pytest.mark.slow
def test_the_first_commands_run_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    lines = [ln.split("#", 1)[0].strip() for ln in _blocks("bash")[2].splitlines()]  # [0], [1]: the two commands
    lines = [ln for ln in lines if ln][:4]
    assert [shlex.split(ln)[1] for ln in lines] == ["simulate", "calibrate", "check", "target"]
    for line in lines:
        assert main(shlex.split(line)[1:]) == 0, line
    printed = capsys.readouterr().out
    assert "cam2base" in printed and (tmp_path / "results" / "result.json").exists()
    assert (tmp_path / "board.pdf").read_bytes().startswith(b"%PDF")


def test_the_links_lead_to_files():
    for doc in [README, *sorted((README.parent / "docs").glob("*.md"))]:
        for link in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", doc.read_text()):
            if not link.startswith("http"):
                assert (doc.parent / link).exists(), f"{doc.name}: {link}"


def test_refine_help_and_the_guide_tell_the_same_choice():
    """--refine's help and docs/guide.md's account of 'auto' name the same candidates and rules: the
    closed forms but horaud_nonlinear, the pixel refinement preferred up to 1.2x PnP's residual, the
    one-standard-error rule, and reprojection's robot poses corrected under --robot-noise."""
    from handeye.cli._common import REFINE_HELP
    from handeye.estimation.estimators import ROBOT_DOMINATES, SLOW_CLOSED_FORMS

    guide = (README.parent / "docs" / "guide.md").read_text(encoding="utf-8")
    helps = " ".join(REFINE_HELP.values())
    for text in (helps, guide):
        assert f"{ROBOT_DOMINATES:g}x" in text and "one standard error" in text
        assert all(name in text for name in SLOW_CLOSED_FORMS)
    assert "robot-noise" in REFINE_HELP["reprojection"] and "robot_noise" in guide
