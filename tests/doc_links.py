#!/usr/bin/python3
"""Every relative link of the documentation resolves.

  /usr/bin/python3 tests/doc_links.py [REPO_ROOT] [FILE.md ...]

Checks README.md, CHANGELOG.md, cluster/README.md and docs/**/*.md (or the files given): every
Markdown link [text](target), image ![alt](target) and reference definition [id]: target whose
target is not a URL must name a file or directory of the repository (relative to the page; a leading / is the repository root),
not one that git ignores (build outputs), and its #anchor, if any, a heading of that page
(GitHub's rule: lower case, punctuation dropped, spaces to hyphens, -1, -2, ... for repeats) or an
explicit <a name=...>/<a id=...>. Links inside code spans and fenced code blocks are text, not
links. Prints each broken link as FILE:LINE: TARGET: why, and exits 1 if there is any.
"""
import os
import re
import subprocess
import sys
import unicodedata

URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")  # http:, https:, mailto:, ...
FENCE = re.compile(r"^\s{0,3}(`{3,}|~{3,})")
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
SETEXT = re.compile(r"^\s{0,3}(=+|-+)\s*$")
EXPLICIT_ANCHOR = re.compile(r"<a\s+(?:name|id)\s*=\s*[\"']([^\"']+)[\"']", re.I)
REFERENCE = re.compile(r"^\s{0,3}\[([^\]]+)\]:\s*(<[^>]*>|\S+)")


def strip_code_spans(line):
    """The line with inline code spans blanked out (same length, so columns stay)."""
    out, i = [], 0
    while i < len(line):
        if line[i] == "`":
            n = len(line) - len(line[i:].lstrip("`"))
            ticks = line[i:i + n]
            end = line.find(ticks, i + n)
            if end >= 0:
                out.append(" " * (end + n - i))
                i = end + n
                continue
            out.append(ticks)
            i += n
            continue
        out.append(line[i])
        i += 1
    return "".join(out)


def inline_links(text):
    """Targets of [text](target) and ![alt](target) in one line (code spans already blanked)."""
    targets, i = [], 0
    while True:
        i = text.find("](", i)
        if i < 0:
            return targets
        j, depth = i + 2, 1
        while j < len(text) and depth:  # the target may hold balanced parentheses
            depth += {"(": 1, ")": -1}.get(text[j], 0)
            j += 1
        if depth == 0:
            targets.append(text[i + 2:j - 1])
        i = j


def clean_target(raw):
    t = raw.strip()
    if t.startswith("<") and ">" in t:
        return t[1:t.index(">")]
    return t.split()[0] if t.split() else ""  # drop a "title"


def slug(heading):
    """GitHub's anchor for a heading's text."""
    text = re.sub(r"!\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # images -> alt text
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links -> their text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    text = text.replace("`", "").lower()
    kept = []
    for ch in text:
        if ch in " -_" or unicodedata.category(ch)[0] in "LN":
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def markdown_lines(path):
    """(line number, text) of the lines outside fenced code blocks."""
    fence = None
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            line = line.rstrip("\n")
            m = FENCE.match(line)
            if fence is None and m:
                fence = m.group(1)[0] * len(m.group(1))
                continue
            if fence is not None:
                if line.strip().startswith(fence):
                    fence = None
                continue
            yield number, line


def anchors(path, cache={}):
    """The anchors a Markdown page defines."""
    if path in cache:
        return cache[path]
    found, seen, previous = set(), {}, ""
    for _, line in markdown_lines(path):
        text = None
        m = HEADING.match(line)
        if m:
            text = m.group(2)
        elif SETEXT.match(line) and previous.strip() and not previous.lstrip().startswith(("|", "-", "*")):
            text = previous.strip()
        if text is not None:
            base = slug(text)
            n = seen.get(base, 0)
            found.add(base if n == 0 else f"{base}-{n}")
            seen[base] = n + 1
        found.update(EXPLICIT_ANCHOR.findall(line))
        previous = line
    cache[path] = found
    return found


def ignored_by_git(root, path):
    try:
        r = subprocess.run(["git", "-C", root, "check-ignore", "-q", "--no-index", path],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return False
    return r.returncode == 0


def check(root, page):
    """Broken links of one page: [(line, target, why)]."""
    broken = []
    here = os.path.dirname(page)
    for number, line in markdown_lines(page):
        text = strip_code_spans(line)
        targets = inline_links(text)
        m = REFERENCE.match(text)
        if m:
            targets.append(m.group(2))
        for raw in targets:
            target = clean_target(raw)
            if not target or URL.match(target):
                continue
            path, _, anchor = target.partition("#")
            if path:
                file = os.path.normpath(os.path.join(root, path.lstrip("/")) if path.startswith("/")
                                        else os.path.join(here, path))
                if os.path.relpath(file, root).startswith(".."):
                    broken.append((number, target, "points outside the repository"))
                    continue
                if not os.path.exists(file):
                    broken.append((number, target, "no such file"))
                    continue
                if ignored_by_git(root, os.path.relpath(file, root)):
                    broken.append((number, target, "a file git ignores (a build output?)"))
                    continue
            else:
                file = page
            if anchor:
                if file.endswith(".md") and os.path.isfile(file):
                    if anchor not in anchors(file):
                        broken.append((number, target, f"no heading '#{anchor}' in {os.path.relpath(file, root)}"))
                elif not re.fullmatch(r"L\d+(-L\d+)?", anchor):
                    broken.append((number, target, "an anchor into a file that is not a Markdown page"))
    return broken


def pages(root):
    found = [os.path.join(root, name) for name in ("README.md", "CHANGELOG.md", os.path.join("cluster", "README.md"))]
    for d, dirs, files in os.walk(os.path.join(root, "docs")):
        dirs.sort()
        found += [os.path.join(d, f) for f in sorted(files) if f.endswith(".md")]
    return [p for p in found if os.path.isfile(p)]


def main(argv):
    root = os.path.abspath(argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(__file__), ".."))
    todo = [os.path.abspath(p) for p in argv[2:]] or pages(root)
    bad = 0
    for page in todo:
        for number, target, why in check(root, page):
            print(f"{os.path.relpath(page, root)}:{number}: {target}: {why}")
            bad += 1
    if bad:
        print(f"doc_links: {bad} broken link(s) in {len(todo)} page(s)")
        return 1
    print(f"doc_links: every relative link of {len(todo)} page(s) resolves")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
