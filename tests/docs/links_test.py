#!/usr/bin/env python3
"""The README and docs/ point at files that exist: every relative Markdown link (images too) and
every backticked repository path (`docs/...`, `render/...`, `bench/...`, ...). The README's long
sections live in docs/guide/ and the measurements in docs/bench/; a file moved or renamed
without its references fails here.

Usage: links_test.py REPO_ROOT
"""
import glob
import os
import re
import sys

TOP_DIRS = ("docs", "bench", "render", "cache", "tests", "deploy", "coordinator", "worker",
            "cli", "service", "proto", "examples")
LINK = re.compile(r"\]\(([^)#\s]+)")
PATH = re.compile(r"`((?:%s)/[A-Za-z0-9_./-]+)`" % "|".join(TOP_DIRS))


def main():
    root = os.path.abspath(sys.argv[1])
    files = [os.path.join(root, "README.md")] + sorted(
        glob.glob(os.path.join(root, "docs", "**", "*.md"), recursive=True))
    missing = []
    for f in files:
        text = open(f, encoding="utf-8").read()
        here = os.path.dirname(f)
        for m in LINK.finditer(text):
            target = m.group(1)
            if "://" in target or target.startswith("mailto:"):
                continue
            if not os.path.exists(os.path.join(here, target)):
                missing.append((f, "link", target))
        for m in PATH.finditer(text):
            target = m.group(1).rstrip(".")
            if any(c in target for c in "*{}"):
                continue
            if not os.path.exists(os.path.join(root, target)):
                missing.append((f, "path", target))
    for f, kind, target in missing:
        print("%s: %s %s does not exist" % (os.path.relpath(f, root), kind, target))
    print("checked %d files, %d missing" % (len(files), len(missing)))
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
