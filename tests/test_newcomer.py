"""A newcomer's first hour, as the README tells it: every command and snippet, as written, in a new folder.

The README's ``bash`` blocks run in a shell (``pip install`` steps are the set-up this interpreter already
has; the test command is this suite), its ``python`` blocks run as scripts, and a block the README
introduces as a file ("In `mypol.py`:") is written to that file, as a user would. Nothing may fail or
print a traceback, the user's own function must be evaluated beside ``yielding``, and no run may replace
an earlier one.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
FILE_INTRO = re.compile(r"In `([\w./-]+\.py)`:\s*$")
TIMEOUT_S = 600


def readme_blocks() -> list[tuple[str, str, str | None]]:
    """(language, code, file it is introduced as) of every fenced block with a language, in order."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    blocks, end = [], 0
    for match in BLOCK.finditer(text):
        prose = text[end : match.start()].rstrip()
        end = match.end()
        if match.group(1):
            intro = FILE_INTRO.search(prose)
            blocks.append((match.group(1), match.group(2), intro.group(1) if intro else None))
    return blocks


def shell_commands(code: str) -> list[str]:
    """The commands a newcomer runs from a bash block, less the set-up this environment already has."""
    commands = []
    for line in code.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = [p.strip() for p in line.split("&&")]
        kept = [p for p in parts if not p.startswith("pip install") and not p.startswith("python -m pytest")]
        if kept:
            commands.append(" && ".join(kept))
    return commands


def test_the_readme_finds_its_blocks():
    blocks = readme_blocks()
    languages = {lang for lang, _, _ in blocks}
    assert {"bash", "python"} <= languages
    assert any(path == "mypol.py" for _, _, path in blocks)
    commands = [c for lang, code, _ in blocks if lang == "bash" for c in shell_commands(code)]
    assert "crossing-eval" in commands  # the main job, once the install step is dropped
    assert not any("pytest" in c or c.startswith("pip") for c in commands)


@pytest.mark.slow
def test_a_newcomer_runs_the_readme_as_written(tmp_path: Path):
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    env.pop("PYTHONPATH", None)  # only what the install provides, as on a fresh machine
    (tmp_path / "examples").symlink_to(REPO / "examples")  # "from the folder that holds it"
    outputs = []
    for n, (lang, code, path) in enumerate(readme_blocks()):
        if path is not None:
            (tmp_path / path).write_text(code, encoding="utf-8")
            continue
        if lang == "python":
            script = tmp_path / f"snippet_{n}.py"
            script.write_text(code, encoding="utf-8")
            runs = [[sys.executable, str(script)]]
        elif lang == "bash":
            runs = [["bash", "-c", command] for command in shell_commands(code)]
        else:
            continue
        for argv in runs:
            proc = subprocess.run(
                argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=TIMEOUT_S, check=False
            )
            said = proc.stdout + proc.stderr
            assert proc.returncode == 0, f"{argv[-1]!r} failed ({proc.returncode}):\n{said[-3000:]}"
            assert "Traceback" not in said, f"{argv[-1]!r} printed a traceback:\n{said[-3000:]}"
            outputs.append(said)
            if argv[-1] == "crossing-eval":  # the main job fits a terminal 120 columns wide
                assert max(len(line) for line in proc.stdout.splitlines()) < 120
    assert any("mypol:cruise" in out and "yielding" in out for out in outputs)  # their function, evaluated
    parent = tmp_path / "crossing-eval-results"
    runs = [p for p in parent.iterdir() if p.is_dir() and not p.is_symlink()]
    assert len(runs) == sum("crossing-eval" in o and "episodes in" in o for o in outputs) >= 3  # all kept
    assert (parent / "latest" / "results.json").is_file()
