#!/usr/bin/env python3
"""Every ```json block in the pages a user copies from parses as JSON.

A reader pastes these blocks into files (a study definition, a scene); a comment or a
trailing comma in one makes `aliquot study` or a scene load refuse the file. docs/API.md is
not checked: its blocks show response shapes with `...` where a list goes on.
Usage: tests/docs/json_blocks_test.py [FILE.md ...]   (default: the pages below)
"""
import json
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
PAGES = ["README.md", "docs/STUDIES.md", "docs/SCENES.md", "docs/WALKTHROUGH.md"]
BLOCK = re.compile(r"^```json\n(.*?)^```", re.S | re.M)


def bad_blocks(path):
    text = path.read_text(encoding="utf-8")
    for match in BLOCK.finditer(text):
        line = text.count("\n", 0, match.start()) + 2  # the block's first line
        try:
            json.loads(match.group(1))
        except json.JSONDecodeError as error:
            yield f"{path}:{line + error.lineno - 1}: {error.msg}"


def main(args):
    paths = [pathlib.Path(a) for a in args] or [ROOT / p for p in PAGES]
    failures = [f for p in paths for f in bad_blocks(p)]
    for failure in failures:
        print(f"json_blocks_test: {failure}", file=sys.stderr)
    blocks = sum(len(BLOCK.findall(p.read_text(encoding="utf-8"))) for p in paths)
    print(f"json_blocks_test: {blocks} JSON blocks in {len(paths)} pages, {len(failures)} bad")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
