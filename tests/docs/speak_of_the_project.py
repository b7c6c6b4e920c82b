#!/usr/bin/env python3
"""The repository speaks of itself only: no numbered work periods, no paper numbering instead of a
citation, no files outside the repository cited as sources, no tools that do not ship with it; and every
relative link in a Markdown file points to a file that exists.

Usage: speak_of_the_project.py SOURCE_DIR     (exit 0 when clean, 1 with one line per finding)
"""
import pathlib
import re
import sys

# Built from pieces so that this file does not match itself (nor any check for such words).
PLAN_FILES = "(" + "DES" + "IGN|" + "STY" + "LE)"
FORBIDDEN = [
    (re.compile(r"\b" + "ses" + r"sions?\s+\d+", re.I), "a numbered work period"),
    (re.compile(r"\b" + "se" + r"ed\s+(paper|00\d)\b|\bthe\s+(YADE|Kratos|rockfall)\s+" + "se" + r"ed\b", re.I),
     "paper numbering instead of a citation"),
    (re.compile(r"\.\./" + "sha" + "red|" + r"\b" + "sha" + "red/" + "reference"), "a path outside the repository"),
    (re.compile(r"\b" + PLAN_FILES + r"\.md\b|\b" + "DES" + "IGN §"), "a design file that does not ship"),
    (re.compile(r"\b" + "far" + r"m-(bench|studio)\b"), "a tool that does not ship"),
    (re.compile(r"\bdevelopment " + r"machine\b|\bthe user " + r"asked\b", re.I), "the story of the project's making"),
]
SKIP_DIRS = {".git", "node_modules"}
TEXT = {".md", ".txt", ".yaml", ".yml", ".py", ".sh", ".cpp", ".hpp", ".h", ".c", ".cmake", ".json", ".geo"}
# Each pattern must catch its example, so a broken pattern fails the test instead of passing everything.
EXAMPLES = ["in ses" + "sion 23 we", "the YADE " + "se" + "ed", "see ../" + "sha" + "red/x", "DES" + "IGN" + ".md §3",
            "far" + "m-bench ran", "the development" + " machine"]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def files(root):
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if any(part in SKIP_DIRS or part.startswith("build") for part in rel.parts[:-1]) or not p.is_file():
            continue
        if p.suffix in TEXT or p.name in ("Makefile", "CMakeLists.txt") or rel.parts[0] == ".ci":
            yield p, rel


def main():
    root = pathlib.Path(sys.argv[1]).resolve()
    me = pathlib.Path(__file__).resolve()
    findings, scanned = [], 0
    for (pattern, what), example in zip(FORBIDDEN, EXAMPLES):
        if not pattern.search(example):
            findings.append(f"the pattern for {what} misses its example \"{example}\"")
    for path, rel in files(root):
        if path.resolve() == me:
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        scanned += 1
        for number, line in enumerate(text.splitlines(), 1):
            for pattern, what in FORBIDDEN:
                m = pattern.search(line)
                if m:
                    findings.append(f"{rel}:{number}: {what}: \"{m.group(0)}\"")
            if path.suffix == ".md":
                for target in LINK.findall(line):
                    if re.match(r"[a-z]+:", target) or target.startswith("#"):
                        continue
                    local = target.split("#", 1)[0]
                    if local and not (path.parent / local).exists():
                        findings.append(f"{rel}:{number}: link to a file that does not exist: {target}")
    for f in findings:
        print(f)
    print(f"{scanned} files read, {len(findings)} findings")
    if scanned < 200:
        print("too few files read: is SOURCE_DIR the repository root?")
        return 1
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
