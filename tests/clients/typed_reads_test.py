#!/usr/bin/env python3
"""The clients read the server's answers through api/ types, never by string
key (docs/ARCHITECTURE.md, "Clients read typed answers").

Scans the C++ clients (clients/cli, its study/, clients/dds_monitor) for a
JSON member read by a literal key:

    x["key"]   (not followed by an assignment: writing a request body is not a read)
    x.at("key")   x.value("key", ...)   x.contains("key")

and fails listing file:line for each. The scanner cannot tell a JSON value from
a std::map keyed by string, so a map read by a literal key carries the line
`// typed-reads: not JSON (what it is)` just above it; such lines are counted
and printed.

Exempt files:
  - clients/cli/config.cc parses the command line's own configuration file,
    not a server's answer.

Usage: typed_reads_test.py SOURCE_DIR
"""

import pathlib
import re
import sys

SCANNED = ["clients/cli", "clients/dds_monitor"]
EXEMPT = {
    "clients/cli/config.cc": "parses the CLI's own configuration file",
}
MARKER = "// typed-reads: not JSON"

KEY = r'"(?:[^"\\]|\\.)*"'
SUBSCRIPT = re.compile(r"\[\s*" + KEY + r"\s*\](?!\s*=[^=])")
CALL = re.compile(r"\.(?:at|value|contains)\(\s*" + KEY)


def code_of(line):
    """The line without a trailing // comment (outside string literals)."""
    in_string = False
    i = 0
    while i < len(line):
        c = line[i]
        if c == "\\" and in_string:
            i += 2
            continue
        if c == '"':
            in_string = not in_string
        elif not in_string and line.startswith("//", i):
            return line[:i]
        i += 1
    return line


def scan(path):
    """(line number, text) of every string-key read; the count of marked lines."""
    reads, marked = [], 0
    previous = ""
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        code = code_of(line)
        if SUBSCRIPT.search(code) or CALL.search(code):
            if previous.strip().startswith(MARKER):
                marked += 1
            else:
                reads.append((number, line.strip()))
        previous = line
    return reads, marked


def main():
    root = pathlib.Path(sys.argv[1])
    failures = []
    for relative, why in EXEMPT.items():
        print(f"exempt: {relative} ({why})")
    for directory in SCANNED:
        for path in sorted((root / directory).rglob("*")):
            if path.suffix not in (".cc", ".h"):
                continue
            relative = path.relative_to(root).as_posix()
            if relative in EXEMPT:
                continue
            reads, marked = scan(path)
            if marked:
                print(f"{relative}: {marked} marked map read(s)")
            failures += [f"{relative}:{n}: {text}" for n, text in reads]
    if failures:
        print("\nstring-key reads of JSON in the clients (read answers through api/ types):")
        print("\n".join(failures))
        return 1
    print("no string-key reads outside the exempt files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
