#!/usr/bin/env python3
"""Lists import cycles between the modules of Rust crates.

Usage: python3 modcycles.py CRATE_DIR... [--edges] [--tests] [--paths-only]

Each file under CRATE_DIR/src is a module (lib.rs is `crate`, a/mod.rs and a.rs are `a`).
A module depends on another when its code names it: `use crate::x`, `crate::x::y` in code,
`super::...`, `self::child::...` or a bare `child::...` for a child it declares. Items that
the crate root re-exports (`pub use a::B;` in lib.rs) resolve to the module that defines
them; the root's own `pub use` lines are not counted as dependencies of the root.
`#[cfg(test)]` modules and tests.rs files are left out unless --tests is given.
With --paths-only, only `crate::`, `super::` and `self::` paths count: a parent naming its
own child by a bare path (`child::item`, `pub use child::Item`) is not a dependency.
Exits 1 when a cycle is found.
"""
import os, re, sys

def strip_comments(src):
    src = re.sub(r'/\*.*?\*/', '', src, flags=re.S)
    out = []
    for line in src.split('\n'):
        # drop // comments (naive about strings containing //, good enough for paths)
        i = line.find('//')
        if i >= 0 and line[:i].count('"') % 2 == 0:
            line = line[:i]
        out.append(line)
    return '\n'.join(out)

def strip_strings(src):
    return re.sub(r'"(?:\\.|[^"\\])*"', '""', src)

def strip_test_mods(src):
    """Removes `#[cfg(test)] mod x { ... }` blocks and `#[cfg(test)] mod x;` lines."""
    out, i = [], 0
    pat = re.compile(r'#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*([;{])')
    while True:
        m = pat.search(src, i)
        if not m:
            out.append(src[i:]); break
        out.append(src[i:m.start()])
        if m.group(3) == ';':
            i = m.end(); continue
        depth, j = 1, m.end()
        while j < len(src) and depth:
            depth += {'{': 1, '}': -1}.get(src[j], 0); j += 1
        i = j
    return ''.join(out)

def module_files(crate):
    src = os.path.join(crate, 'src')
    mods = {}
    for root, _, files in os.walk(src):
        for f in files:
            if not f.endswith('.rs'): continue
            p = os.path.join(root, f)
            rel = os.path.relpath(p, src)[:-3].split(os.sep)
            if rel == ['main'] or rel[0] == 'bin': continue
            if rel[-1] in ('mod', 'lib'): rel = rel[:-1]
            mods['::'.join(['crate'] + rel)] = p
    return mods

def use_paths(text):
    """Expands `use a::{b, c::{d}}` into full paths."""
    paths = []
    for m in re.finditer(r'\buse\s+([^;]+);', text):
        paths += expand(re.sub(r'\s+', '', m.group(1)))
    return paths

def expand(s):
    i = s.find('{')
    if i < 0:
        return [s.split(' as ')[0].replace('as', ' as ').split(' as ')[0]] if s else []
    prefix, body = s[:i], s[i + 1:s.rfind('}')]
    parts, depth, cur = [], 0, ''
    for ch in body:
        if ch == ',' and depth == 0:
            parts.append(cur); cur = ''; continue
        depth += (ch == '{') - (ch == '}'); cur += ch
    parts.append(cur)
    res = []
    for p in parts:
        p = re.sub(r'as\w+$', '', p) if False else p
        for e in expand(p):
            res.append(prefix + e if e != 'self' else prefix.rstrip(':'))
    return res

def main():
    args = [a for a in sys.argv[1:] if not a.startswith('--')]
    show_edges, tests = '--edges' in sys.argv, '--tests' in sys.argv
    paths_only = '--paths-only' in sys.argv
    found = False
    for crate in args:
        mods = module_files(crate)
        if not tests:
            mods = {m: p for m, p in mods.items() if not m.endswith('::tests')}
        texts = {}
        for m, p in mods.items():
            t = strip_strings(strip_comments(open(p).read()))
            texts[m] = t if tests else strip_test_mods(t)
        # root re-exports: name -> full path
        reexp = {}
        for path in use_paths(re.sub(r'(?m)^(?!\s*pub\s+use).*$', '', texts.get('crate', ''))):
            path = re.sub(r'^(crate|self)::', '', path)
            name = path.split('::')[-1]
            reexp[name] = 'crate::' + path
        def resolve(full):
            parts = full.split('::')
            if len(parts) >= 2 and parts[0] == 'crate' and 'crate::' + parts[1] not in mods and parts[1] in reexp:
                return resolve(reexp[parts[1]] + ('::' + '::'.join(parts[2:]) if parts[2:] else ''))
            best = 'crate'
            for k in range(1, len(parts) + 1):
                cand = '::'.join(parts[:k])
                if cand in mods: best = cand
            return best
        graph, why = {}, {}
        for m, t in texts.items():
            here = m.split('::')
            children = set(re.findall(r'(?m)^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;', t))
            refs = []
            code = t
            if m == 'crate':
                code = re.sub(r'(?m)^\s*pub\s+use[^;]*;', '', code)
            for p in use_paths(code) + re.findall(r'(?<![\w:])((?:crate|super|self)(?:::\w+)+)', code):
                refs.append(p)
            for c in ([] if paths_only else children):
                for _ in re.findall(r'(?<![\w:])' + c + r'::\w+', code):
                    refs.append('self::' + c)
            deps = {}
            for p in refs:
                parts = p.split('::')
                base = list(here)
                while parts and parts[0] in ('super', 'self'):
                    if parts[0] == 'super': base = base[:-1]
                    parts = parts[1:]
                if p.startswith('crate'):
                    full = p
                elif p.split('::')[0] in ('super', 'self'):
                    full = '::'.join(base + parts)
                else:
                    continue  # external crate or std
                d = resolve(full)
                if d != m: deps.setdefault(d, set()).add(p)
            why[m] = deps
            graph[m] = set(deps)
        if show_edges:
            for m in sorted(graph):
                print(f'{m} -> {", ".join(sorted(graph[m]))}')
        # strongly connected components (Tarjan)
        index, low, stack, on, sccs, n = {}, {}, [], set(), [], [0]
        sys.setrecursionlimit(10000)
        def visit(v):
            index[v] = low[v] = n[0]; n[0] += 1; stack.append(v); on.add(v)
            for w in graph.get(v, ()):
                if w not in graph: continue
                if w not in index:
                    visit(w); low[v] = min(low[v], low[w])
                elif w in on:
                    low[v] = min(low[v], index[w])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop(); on.discard(w); comp.append(w)
                    if w == v: break
                if len(comp) > 1: sccs.append(sorted(comp))
        for v in sorted(graph):
            if v not in index: visit(v)
        for comp in sccs:
            found = True
            print(f'{crate}: cycle among {", ".join(comp)}')
            for a in comp:
                for b in sorted(graph[a] & set(comp)):
                    print(f'    {a} -> {b}   ({", ".join(sorted(why[a][b]))})')
        if not sccs:
            print(f'{crate}: no cycles ({len(graph)} modules)')
    sys.exit(1 if found else 0)

main()
