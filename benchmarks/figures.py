"""Keep the printed examples in the docs true: run them and compare, or rewrite them.

A checked example is a fenced block whose first line is ``$ slopelander ...``: the command is run
(this checkout's code, in a temporary folder, so files it writes land there) and every line it
prints is compared with the lines under it, except the lines that name a path or a wall time.
Every other ``slopelander`` command line in a code block of the README and the docs is parsed with
the command's own argument parser, so an option that was renamed or removed is caught without
running the (slow) command.

Usage:
    python3 benchmarks/figures.py --check          # exit 1 and show what differs
    python3 benchmarks/figures.py --write          # refresh the checked examples in place
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RUN_PAGES = [ROOT / "README.md", ROOT / "docs" / "figures.md"]
RUNNABLE = ("simulate", "lookup", "params")  # answer in seconds; the rest are only parsed
VOLATILE = re.compile(r"^(table|plot|csv): |\bwall\b")
FENCE = re.compile(r"^```[\w-]*\n(.*?)^```", re.S | re.M)


@dataclass
class Example:
    page: Path
    command: str
    printed: list[str]
    start: int  # offset of the block's body in the page


def examples(page: Path) -> list[Example]:
    """The checked examples of one page."""
    text = page.read_text()
    out = []
    for m in FENCE.finditer(text):
        lines = m.group(1).splitlines()
        if lines and lines[0].startswith("$ slopelander "):
            out.append(Example(page, lines[0][2:], lines[1:], m.start(1)))
    return out


def run(command: str) -> list[str]:
    """What the command prints, run from a temporary folder with this checkout's code."""
    argv = shlex.split(command)
    assert argv[0] == "slopelander" and argv[1] in RUNNABLE, f"not a quick command: {command}"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    code = "import sys; from slopelander.cli import main; sys.exit(main(sys.argv[1:]))"
    with tempfile.TemporaryDirectory() as tmp:
        done = subprocess.run(
            [sys.executable, "-c", code, *argv[1:]], cwd=tmp, env=env, capture_output=True, text=True
        )
    if done.returncode != 0:
        raise RuntimeError(f"{command} failed ({done.returncode}): {done.stderr.strip()}")
    return [line.replace(f"{ROOT}{os.sep}", "") for line in done.stdout.splitlines()]  # checkout paths


def differences(example: Example, printed: list[str]) -> list[str]:
    """Lines that matter, documented against printed, as a short list of what differs."""
    want = [line for line in example.printed if not VOLATILE.search(line)]
    got = [line for line in printed if not VOLATILE.search(line)]
    if want == got:
        return []
    rows = [f"{example.page.name}: $ {example.command}"]
    for n in range(max(len(want), len(got))):
        a = want[n] if n < len(want) else "<missing>"
        b = got[n] if n < len(got) else "<missing>"
        if a != b:
            rows += [f"  page: {a}", f"  now:  {b}"]
    return rows


def command_lines(page: Path) -> list[tuple[int, str]]:
    """Every ``slopelander`` command in the page's code blocks (fenced or indented), with its line."""
    found, in_fence, lines = [], False, page.read_text().splitlines()
    joined: list[tuple[int, str]] = []
    n = 0
    while n < len(lines):
        line, start = lines[n], n
        while line.endswith("\\") and n + 1 < len(lines):
            n += 1
            line = line[:-1] + " " + lines[n].strip()
        joined.append((start + 1, line))
        n += 1
    for number, line in joined:
        if line.startswith("```"):
            in_fence = not in_fence
            continue
        if not (in_fence or line.startswith("    ")):
            continue
        for part in re.split(r"&&|;|\|", line):
            part = part.strip().removeprefix("$ ")
            if part.startswith("slopelander ") and not re.search(r"[$\[<]", part):  # not a synopsis
                found.append((number, part.split(" #")[0].strip()))
    return found


def parse_problem(command: str) -> str | None:
    """Why the command's own parser refuses the command, or None."""
    sys.path[:0] = [str(ROOT / "src"), str(ROOT)]
    from slopelander.cli import build_parser

    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            build_parser().parse_args(shlex.split(command)[1:])
    except SystemExit as exc:
        if exc.code:
            return err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else f"exit {exc.code}"
    return None


def check() -> list[str]:
    problems = []
    for page in PAGES:
        for number, command in command_lines(page):
            why = parse_problem(command)
            if why:
                problems.append(f"{page.relative_to(ROOT)}:{number}: {command}: {why}")
    for page in RUN_PAGES:
        for example in examples(page):
            problems += differences(example, run(example.command))
    return problems


def write() -> None:
    for page in RUN_PAGES:
        text = page.read_text()
        for example in reversed(examples(page)):
            body = "\n".join([f"$ {example.command}", *run(example.command)]) + "\n"
            old = "\n".join([f"$ {example.command}", *example.printed]) + "\n"
            assert text[example.start : example.start + len(old)] == old
            text = text[: example.start] + body + text[example.start + len(old) :]
        page.write_text(text)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="compare, exit 1 on a difference")
    mode.add_argument("--write", action="store_true", help="rewrite the checked examples")
    args = parser.parse_args()
    if args.write:
        write()
        return 0
    problems = check()
    print("\n".join(problems) if problems else "every example matches and every command parses")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
