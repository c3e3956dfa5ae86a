"""docs/tutorial.md runs as written (issue 60, item 3): every ``handeye`` command of its bash blocks,
in order, in one folder, on the simulated cell where a block needs hardware (the block says so); a
block that needs a browser (``handeye live`` serves a page until Ctrl-C) is parsed, not run: the page
runs in tests/test_live.py."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from handeye.cli import main

TUTORIAL = Path(__file__).resolve().parents[1] / "docs" / "tutorial.md"


def _commands(browser: bool = False) -> list[tuple[str, bool]]:
    """Each handeye command of the bash blocks, in order (continuation lines joined), and whether
    its block says it needs the hardware; those of the blocks that need a browser only with ``browser``."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", TUTORIAL.read_text(), flags=re.S):
        hardware = "needs the hardware" in block
        if ("needs a browser" in block) != browser:
            continue
        for command in block.replace("\\\n", " ").splitlines():
            if command.strip().startswith("handeye "):
                out.append((command.strip(), hardware))
    return out


def test_the_browser_commands_of_the_tutorial_parse():
    """``handeye live`` serves until Ctrl-C: its commands are checked against the parser (they exist,
    with these options), and the page itself runs in tests/test_live.py."""
    from handeye.cli import build_parser

    commands = _commands(browser=True)
    assert [c.split()[1] for c, _ in commands] == ["live"]
    for command, _ in commands:
        args = build_parser().parse_args(shlex.split(command)[1:])
        assert args.command == "live" and args.robot == "sim" and args.camera == "sim"


@pytest.mark.slow
def test_every_tutorial_command_runs_as_written_in_order(tmp_path, monkeypatch, capsys):
    commands = _commands()
    assert [c for c, _ in commands][:1] == ["handeye target --type charuco --out board.pdf"]
    assert sum(h for _, h in commands) == 1  # only the real arm's acquire needs the hardware
    monkeypatch.chdir(tmp_path)
    ran = []
    for command, hardware in commands:
        if hardware:
            continue
        status = main(shlex.split(command)[1:])
        text = capsys.readouterr()
        assert status in (0, 1), f"{command}: exit {status}\n{text.out[-1500:]}\n{text.err[-1500:]}"
        ran.append((command.split()[1], status))
    assert [name for name, _ in ran] == ["target", "acquire", "check", "calibrate", "verify"]
    assert dict(ran)["calibrate"] == 0 and dict(ran)["verify"] == 0  # X good, and the second capture predicted as promised
    assert (tmp_path / "board.yaml").is_file() and (tmp_path / "cell-results" / "report.html").is_file()
    assert (tmp_path / "cell-results" / "handeye_static_tf.launch.py").is_file() and (tmp_path / "check").is_dir()
