#!/usr/bin/env python3
"""Function lengths in the host's Rust (host-tools/src and sim/src by default): each `fn`
from its signature line to its closing brace, inclusive, longest first.

    python3 scripts/fn-lengths.py [--top N] [--over LINES] [DIR ...]

`--over LINES` lists only functions longer than LINES and exits 1 if a listed one has no
reason stated: a comment line containing `long:` directly above its signature (or above
its attributes and doc comment).
Where it stops: braces are counted in the text with string literals, char literals and
comments left out; raw strings with `#` delimiters are handled, macros that expand to
functions are not seen, and a closure counts toward the function that holds it. Unit-test
modules count like any other code.
"""

import argparse
import os
import re
import sys

from rust_text import code_only

FN = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:async\s+)?(?:unsafe\s+)?(?:extern\s+\"[^\"]*\"\s+)?fn\s+([A-Za-z_][A-Za-z0-9_]*)")


def functions(path):
    with open(path, encoding="utf-8") as f:
        text = f.read()
    raw = text.split("\n")
    lines = code_only(text).split("\n")
    found = []
    for k, line in enumerate(lines):
        m = FN.match(line)
        if not m:
            continue
        depth, opened, end, nest = 0, False, None, 0
        for j in range(k, len(lines)):
            for ch in lines[j]:
                if ch in "([":
                    nest += 1
                elif ch in ")]":
                    nest -= 1
                elif ch == "{":
                    depth, opened = depth + 1, True
                elif ch == "}":
                    depth -= 1
                elif ch == ";" and not opened and depth == 0 and nest == 0:
                    end = -1  # a declaration without a body (trait method)
                    break
                if opened and depth == 0:
                    end = j
                    break
            if end is not None:
                break
        if end is None or end < 0:
            continue
        # A reason: `long:` in the comments and attributes right above.
        a, reason = k - 1, False
        while a >= 0 and re.match(r"\s*(//|#\[)", raw[a]):
            reason = reason or "long:" in raw[a]
            a -= 1
        found.append((end - k + 1, m.group(1), path, k + 1, reason))
    return found


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="*", default=["host-tools/src", "sim/src"])
    ap.add_argument("--top", type=int, default=0)
    ap.add_argument("--over", type=int, default=0)
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    all_fns = []
    for d in a.dirs:
        d = d if os.path.isabs(d) else os.path.join(root, d)
        for dirpath, _, files in os.walk(d):
            for name in sorted(files):
                if name.endswith(".rs"):
                    all_fns += functions(os.path.join(dirpath, name))
    all_fns.sort(key=lambda f: (-f[0], f[2], f[3]))
    shown = [f for f in all_fns if f[0] > a.over] if a.over else all_fns
    if a.top:
        shown = shown[: a.top]
    for n, name, path, line, reason in shown:
        note = "  (reason stated)" if reason else ""
        print(f"{n:5} {os.path.relpath(path, root)}:{line} {name}{note}")
    if a.over:
        bare = [f for f in shown if not f[4]]
        print(f"{len(shown)} function(s) over {a.over} lines, {len(bare)} without a stated reason")
        return 1 if bare else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
