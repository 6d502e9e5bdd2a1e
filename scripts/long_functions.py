#!/usr/bin/env python3
"""List the Rust functions longer than a limit, longest first (test code left out).

Usage: long_functions.py [--limit N] [--fail] [PATH...]   (default: 120 lines, crates/*/src)

A function's length is the lines from its `fn` line to its closing brace. Left out: files named
`tests.rs` or under a `tests/` folder, and everything inside a `#[cfg(test)]` item. Comments and
string literals are blanked before the braces are counted. With --fail the exit status is 1 when
any function is over the limit.
"""

import glob
import os
import re
import sys

FN = re.compile(r'\bfn\s+([A-Za-z_]\w*)')
CFG_TEST = re.compile(r'#\[cfg\((?:all\()?test\b')


def blank(text):
    """`text` with comments, string and char literals replaced by spaces (newlines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        if text.startswith('//', i):
            j = text.find('\n', i)
            j = n if j < 0 else j
        elif text.startswith('/*', i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith('/*', j):
                    depth, j = depth + 1, j + 2
                elif text.startswith('*/', j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
        elif re.match(r'r#*"', text[i:i + 8]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == '_')):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            j = n if end < 0 else end + 1 + len(hashes)
        elif text[i] == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == '\\' else 1
            j += 1
        elif re.match(r"'(\\.|[^\\'])'", text[i:i + 4]):
            j = i + len(re.match(r"'(\\.|[^\\'])'", text[i:i + 4]).group(0))
        else:
            out.append(text[i])
            i += 1
            continue
        out.append(''.join(c if c == '\n' else ' ' for c in text[i:j]))
        i = j
    return ''.join(out)


def matching_brace(code, open_at):
    """Index of the brace closing the one at `open_at`."""
    depth = 0
    for k in range(open_at, len(code)):
        if code[k] == '{':
            depth += 1
        elif code[k] == '}':
            depth -= 1
            if depth == 0:
                return k
    return len(code) - 1


def test_spans(code):
    """Character spans of the items under `#[cfg(test)]`."""
    spans = []
    for m in CFG_TEST.finditer(code):
        brace, semi = code.find('{', m.end()), code.find(';', m.end())
        if brace >= 0 and (semi < 0 or brace < semi):
            spans.append((m.start(), matching_brace(code, brace)))
    return spans


def functions(path):
    """(lines, line, name) of each function with a body in `path`, test code left out."""
    with open(path, encoding='utf-8') as f:
        code = blank(f.read())
    skip = test_spans(code)
    found = []
    for m in FN.finditer(code):
        if any(a <= m.start() <= b for a, b in skip):
            continue
        # The body: the first `{` after the signature, unless a `;` ends it first (a trait
        # method without a body).
        depth, k = 0, m.end()
        while k < len(code):
            c = code[k]
            if c in '(<[':
                depth += 1
            elif c in ')>]':
                depth = max(0, depth - 1)
            elif c == ';' and depth == 0:
                k = -1
                break
            elif c == '{' and depth == 0:
                break
            k += 1
        if k < 0 or k >= len(code):
            continue
        end = matching_brace(code, k)
        first = code.count('\n', 0, m.start()) + 1
        last = code.count('\n', 0, end) + 1
        found.append((last - first + 1, first, m.group(1)))
    return found


def rust_files(paths):
    for p in paths:
        if os.path.isfile(p):
            yield p
            continue
        for f in sorted(glob.glob(os.path.join(p, '**', '*.rs'), recursive=True)):
            parts = f.split(os.sep)
            if 'tests' in parts or os.path.basename(f) in ('tests.rs',) or 'target' in parts:
                continue
            yield f


def main(argv):
    limit, fail, paths = 120, False, []
    it = iter(argv)
    for a in it:
        if a == '--limit':
            limit = int(next(it))
        elif a == '--fail':
            fail = True
        else:
            paths.append(a)
    paths = paths or sorted(glob.glob('crates/*/src'))
    rows = []
    for f in rust_files(paths):
        for n, line, name in functions(f):
            if n > limit:
                rows.append((n, f'{f}:{line}', name))
    # Nested functions are listed on their own as well as inside their parent.
    for n, where, name in sorted(rows, reverse=True):
        print(f'{n:5d}  {where}  {name}')
    print(f'{len(rows)} functions over {limit} lines')
    return 1 if (fail and rows) else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
