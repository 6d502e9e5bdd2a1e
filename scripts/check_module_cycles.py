#!/usr/bin/env python3
"""Fail on an import circle between the modules (files) of a Rust crate.

Usage: check_module_cycles.py [--self-test] SRC_ROOT...   (a crate root: src/lib.rs or src/main.rs)

The modules of a crate are its files, found from the root through `mod name;` declarations.
File A imports file B when A names an item of B: `use crate::..`, `use super::..`, `use self::..`,
a path `crate::a::b::Item` or `super::Item` in the code, or `child::Item` of a module it declares;
the arrow goes to the deepest module the path walks through. Items of an inline module (`mod x
{ .. }`) count for the file that holds it. Test code is left out, as `cargo modules` leaves it out
by default: modules and inline modules under `#[cfg(test)]` or `#[cfg(all(test, ..))]`. A circle (files that import each other, directly or
through others) is printed with the names that tie it, and the exit status is 1.
"""

import os
import re
import sys
from collections import defaultdict

MOD_DECL = re.compile(r'^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+([A-Za-z_]\w*)\s*;', re.M)
TEST_CFG = re.compile(r'#\[cfg\((?:all\()?test\b')
INLINE_MOD = re.compile(r'^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+([A-Za-z_]\w*)\s*\{')
PATH = re.compile(r'(?<![\w:])((?:crate|super|self)(?:::(?:super|[A-Za-z_]\w*))+)')


class Module:
    def __init__(self, path, file, parent):
        self.path = path          # e.g. ('crate', 'scene', 'sampling')
        self.file = file
        self.parent = parent
        self.children = {}


def strip_comments_and_strings(text):
    """The code with comments and string literals blanked (line structure kept)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith('//', i):
            j = text.find('\n', i)
            j = n if j < 0 else j
            i = j
        elif text.startswith('/*', i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith('/*', j):
                    depth, j = depth + 1, j + 2
                elif text.startswith('*/', j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append('\n' * text.count('\n', i, j))
            i = j
        elif c == 'r' and re.match(r'r#*"', text[i:i + 8]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == '_')):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            end = n if end < 0 else end + 1 + len(hashes)
            out.append('""' + '\n' * text.count('\n', i, end))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == '\\' else 1
            out.append('""' + '\n' * text.count('\n', i, j))
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:i + 4]):
            m = re.match(r"'(\\.|[^\\'])'", text[i:i + 4])
            out.append("' '")
            i += len(m.group(0))
        else:
            out.append(c)
            i += 1
    return ''.join(out)


def drop_test_code(text):
    """`text` without the modules under a test-only cfg: `mod x;` declarations and the bodies of
    inline `mod x { .. }` blocks (lines blanked, so line numbers stay)."""
    lines = text.split('\n')
    out = []
    skipping = None  # brace depth at which the skipped inline module closes
    depth = 0
    pending = False
    for line in lines:
        opened = line.count('{') - line.count('}')
        if skipping is not None:
            depth += opened
            out.append('')
            if depth <= skipping:
                skipping = None
            continue
        if TEST_CFG.search(line):
            pending = True
            out.append('')
            continue
        if pending and re.match(r'^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+\w+\s*;', line):
            pending = False
            out.append('')
            continue
        if pending and INLINE_MOD.match(line):
            pending = False
            skipping = depth
            depth += opened
            out.append('')
            if depth <= skipping:
                skipping = None
            continue
        if pending and not line.strip().startswith('#['):
            pending = False
        depth += opened
        out.append(line)
    return '\n'.join(out)


def load_crate(root_file):
    """The module tree of the crate rooted at `root_file`, and each file's code."""
    code = {}
    root = Module(('crate',), root_file, None)
    stack = [root]
    while stack:
        m = stack.pop()
        text = drop_test_code(strip_comments_and_strings(open(m.file, encoding='utf-8').read()))
        code[m.file] = text
        if os.path.basename(m.file) in ('lib.rs', 'main.rs', 'mod.rs'):
            folder = os.path.dirname(m.file)
        else:
            folder = os.path.splitext(m.file)[0]
        for name in MOD_DECL.findall(text):
            for cand in (os.path.join(folder, name + '.rs'), os.path.join(folder, name, 'mod.rs')):
                if os.path.exists(cand):
                    child = Module(m.path + (name,), cand, m)
                    m.children[name] = child
                    stack.append(child)
                    break
    return root, code


def inline_module_lines(text):
    """The set of line numbers inside an inline `mod x { .. }` block."""
    inside = set()
    depth = 0
    starts = []  # brace depth at which each open inline module started
    for no, line in enumerate(text.split('\n')):
        if INLINE_MOD.match(line):
            starts.append(depth)
        if starts:
            inside.add(no)
        depth += line.count('{') - line.count('}')
        while starts and depth <= starts[-1]:
            starts.pop()
    return inside


def resolve(module, segments):
    """The deepest module that the path `segments` (relative to `module`) walks through."""
    cur = module
    rest = list(segments)
    if rest and rest[0] == 'crate':
        while cur.parent:
            cur = cur.parent
        rest.pop(0)
    elif rest and rest[0] in ('super', 'self'):
        while rest and rest[0] in ('super', 'self'):
            if rest.pop(0) == 'super' and cur.parent:
                cur = cur.parent
    elif rest and rest[0] in module.children:
        pass
    else:
        return None
    for seg in rest:
        if seg in cur.children:
            cur = cur.children[seg]
        else:
            break
    return cur


def use_paths(text):
    """The full paths of the `use` declarations of `text` (groups expanded), with line numbers."""
    out = []
    for m in re.finditer(r'\buse\s+([^;]+);', text):
        line = text.count('\n', 0, m.start())
        for p in expand(m.group(1)):
            out.append((line, p))
    return out


def expand(tree, prefix=''):
    tree = tree.strip()
    m = re.match(r'^(.*?)\{(.*)\}$', tree, re.S)
    if m:
        base = m.group(1).strip().rstrip(':')
        res = []
        depth, cur = 0, ''
        for ch in m.group(2) + ',':
            if ch == ',' and depth == 0:
                if cur.strip():
                    res += expand(cur, prefix + base + '::' if base else prefix)
                cur = ''
                continue
            depth += ch == '{'
            depth -= ch == '}'
            cur += ch
        return res
    tree = re.sub(r'\s+as\s+\w+$', '', tree)
    return [prefix + tree]


def edges_of(root, code):
    """{(file_a, file_b): set of names} for every import of a file by another."""
    edges = defaultdict(set)
    modules = []
    stack = [root]
    while stack:
        m = stack.pop()
        modules.append(m)
        stack.extend(m.children.values())
    for m in modules:
        text = code[m.file]
        inline = inline_module_lines(text)
        refs = []
        for line, p in use_paths(text):
            refs.append((line, p.split('::')))
        for mm in PATH.finditer(text):
            refs.append((text.count('\n', 0, mm.start()), mm.group(1).split('::')))
        for name in m.children:
            for mm in re.finditer(r'(?<![\w:])' + name + r'::([A-Za-z_]\w*)', text):
                refs.append((text.count('\n', 0, mm.start()), [name, mm.group(1)]))
        for line, segs in refs:
            segs = [s for s in segs if s not in ('*', '')]
            if line in inline and segs and segs[0] == 'super':
                segs = segs[1:] or ['self']
            target = resolve(m, segs)
            if target is None or target.file == m.file:
                continue
            edges[(m.file, target.file)].add('::'.join(segs[-2:]))
    return edges


def circles(edges):
    """Strongly connected components of more than one file (Tarjan)."""
    graph = defaultdict(set)
    for a, b in edges:
        graph[a].add(b)
        graph.setdefault(b, set())
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def check(root_file):
    root, code = load_crate(root_file)
    edges = edges_of(root, code)
    found = circles(edges)
    for comp in found:
        print(f'import circle in {root_file}: {len(comp)} files')
        members = set(comp)
        for (a, b), names in sorted(edges.items()):
            if a in members and b in members:
                print(f'  {a} -> {b}: {", ".join(sorted(names))}')
    return not found


def self_test():
    """The check finds a circle through `super::` and a path, and passes the same crate without it."""
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        src = os.path.join(d, 'src')
        os.makedirs(os.path.join(src, 'a'))
        files = {
            'lib.rs': 'pub mod a;\npub mod b;\npub struct Root;\n',
            'a/mod.rs': 'pub mod inner;\npub use inner::Thing;\n',
            'a/inner.rs': 'use crate::b::Other;\npub struct Thing(Other);\n',
            'b.rs': '// crate::a::Thing in a comment is no import\npub struct Other;\n'
                    'pub fn f() -> crate::a::inner::Thing { todo!() }\n',
        }
        for name, text in files.items():
            with open(os.path.join(src, name), 'w') as f:
                f.write(text)
        root = os.path.join(src, 'lib.rs')
        if check(root):
            print('self-test: the circle a/inner.rs -> b.rs -> a/inner.rs was not found')
            return False
        with open(os.path.join(src, 'b.rs'), 'w') as f:
            f.write('// crate::a::Thing in a comment is no import\npub struct Other;\n'
                    'mod tests {\n    use super::*;\n}\n')
        if not check(root):
            print('self-test: a crate without a circle was refused')
            return False
    print('self-test: ok')
    return True


if __name__ == '__main__':
    args = sys.argv[1:]
    ok = True
    if args and args[0] == '--self-test':
        ok = self_test()
        args = args[1:]
    for root_file in args:
        ok = check(root_file) and ok
    sys.exit(0 if ok else 1)
