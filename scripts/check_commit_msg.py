#!/usr/bin/env python
"""Check commit messages against the project's rule: a subject of at most 72 characters saying
what changed, then a blank line, then the why, figures and checks in the body.

As a git hook (checks the message being committed)::

    ln -s ../../scripts/check_commit_msg.py .git/hooks/commit-msg

On a range of commits (exit status 1 if any breaks the rule)::

    python scripts/check_commit_msg.py --range main~10..main
"""

from __future__ import annotations

import argparse
import subprocess
import sys

MAX_SUBJECT = 72


def problems(message: str) -> list[str]:
    """What is wrong with a commit message (empty: nothing). Lines starting with ``#`` are
    git's comments and are ignored."""
    lines = [ln for ln in message.splitlines() if not ln.startswith("#")]
    while lines and not lines[0].strip():
        lines.pop(0)
    if not lines:
        return ["the message is empty"]
    out = []
    subject = lines[0]
    if len(subject) > MAX_SUBJECT:
        out.append(f"subject has {len(subject)} characters (at most {MAX_SUBJECT}): say what changed, "
                   "and move the why and the figures to the body")
    if len(lines) > 1 and lines[1].strip():
        out.append("the second line must be blank (subject, blank line, body)")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("message_file", nargs="?", help="the message file (git's commit-msg hook passes it)")
    p.add_argument("--range", help="check every commit of a git range instead, e.g. main~10..main")
    args = p.parse_args(argv)
    if args.range:
        out = subprocess.run(["git", "log", "--format=%H%x00%B%x01", args.range], capture_output=True, text=True,
                             check=True).stdout
        bad = 0
        for entry in filter(str.strip, out.split("\x01")):
            sha, _, body = entry.strip().partition("\x00")
            for msg in problems(body):
                print(f"{sha[:10]}: {msg}")
                bad += 1
        return 1 if bad else 0
    if not args.message_file:
        p.error("give the message file or --range")
    with open(args.message_file, encoding="utf-8") as f:
        found = problems(f.read())
    for msg in found:
        print(f"commit message: {msg}", file=sys.stderr)
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
