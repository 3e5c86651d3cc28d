#!/usr/bin/env python3
"""Lists the functions longer than N lines (default 80) outside tests, longest first.

Usage, from the repository root: python3 scripts/longfns.py [N]

A function runs from its `fn` line to the closing brace at its own indentation. Files under
tests/ and benches/, files named tests.rs, and everything after a `#[cfg(test)] mod tests`
are left out. Exits 1 when it lists any.
"""
import os
import re
import sys

FN = re.compile(r'^(\s*)(pub(\([^)]*\))? )?(const )?(async )?(unsafe )?fn (\w+)')


def long_functions(path, limit):
    lines = open(path, encoding='utf-8').read().split('\n')
    for i, line in enumerate(lines):
        if re.match(r'\s*#\[cfg\(test\)\]', line) and 'mod tests' in lines[i + 1]:
            return
        m = FN.match(line)
        if not m:
            continue
        close = m.group(1) + '}'
        end = next((j for j in range(i + 1, len(lines)) if lines[j] == close), None)
        if end is not None and end - i + 1 > limit:
            yield end - i + 1, path, i + 1, m.group(7)


def main():
    limit = int(sys.argv[1]) if len(sys.argv) > 1 else 80
    found = []
    for root, dirs, files in os.walk('.'):
        dirs[:] = [d for d in dirs if d not in ('target', '.git', 'tests', 'benches')]
        for f in files:
            if f.endswith('.rs') and f != 'tests.rs':
                found.extend(long_functions(os.path.join(root, f), limit))
    for lines, path, line, name in sorted(found, reverse=True):
        print(f'{lines} {path}:{line} {name}')
    return 1 if found else 0


if __name__ == '__main__':
    sys.exit(main())
