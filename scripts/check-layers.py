#!/usr/bin/env python3
"""Fails when a source file includes a folder its layer may not depend on.

The allowed dependencies are the ```layers block of docs/architecture.md (one line per folder:
the folder, then the folders it may include, '-' for none, '*' for any); this script only
enforces them. Every C++ file under a listed folder is read; an #include "a/b/c.h" names folder
"a/b" (readers/lbh, lblight/solve, ...), and must be the file's own folder or one of its listed
ones. A folder holding C++ files but missing from the table is an error too, so a new folder
needs its line in the document first.

  scripts/check-layers.py [--root DIR] [--doc FILE]
  scripts/check-layers.py --self-test   # the check fails on a planted upward include
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)
SOURCES = ('.h', '.hpp', '.cpp', '.cu', '.cuh')
SKIP = {'build', '.git', 'out', 'shared'}


def read_table(doc):
    text = open(doc, encoding='utf-8').read()
    m = re.search(r'```layers\n(.*?)```', text, re.S)
    if not m:
        sys.exit(f'{doc}: no ```layers block')
    table = {}
    for line in m.group(1).splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        folder, *allowed = line.split()
        table[folder] = set() if allowed == ['-'] else set(allowed)
    return table


def folder_of(path):
    """The table row a file belongs to: the longest listed prefix of its folder."""
    return os.path.dirname(path).replace(os.sep, '/')


def self_test(doc):
    """A copy of the real table over a tree with one upward include and one unlisted folder:
    the check must fail and name both; without them it must pass."""
    def run(files):
        with tempfile.TemporaryDirectory() as root:
            for rel, text in files.items():
                os.makedirs(os.path.join(root, os.path.dirname(rel)), exist_ok=True)
                with open(os.path.join(root, rel), 'w') as f:
                    f.write(text)
            r = subprocess.run([sys.executable, __file__, '--root', root, '--doc', doc],
                               capture_output=True, text=True)
            return r.returncode, r.stdout
    good = {'lblight/solve/a.h': '#include "lblight/core/b.h"\n', 'lblight/core/b.h': '#include <vector>\n'}
    rc, out = run(good)
    if rc != 0:
        print('self-test: a clean tree failed:\n' + out)
        return 1
    bad = dict(good)
    bad['lblight/core/b.h'] = '#include "lblight/solve/a.h"\n'
    bad['lblight/extra/c.h'] = '\n'
    rc, out = run(bad)
    if rc == 0 or 'lblight/core/b.h: includes "lblight/solve/a.h"' not in out or 'lblight/extra' not in out:
        print('self-test: a planted upward include or unlisted folder went unnoticed:\n' + out)
        return 1
    print('check-layers self-test: the check fails on an upward include and on an unlisted folder')
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--root', default=os.path.join(os.path.dirname(__file__), '..'))
    ap.add_argument('--doc', default=None)
    ap.add_argument('--self-test', action='store_true')
    a = ap.parse_args()
    if a.self_test:
        return self_test(a.doc or os.path.join(os.path.abspath(a.root), 'docs', 'architecture.md'))
    root = os.path.abspath(a.root)
    table = read_table(a.doc or os.path.join(root, 'docs', 'architecture.md'))

    def row(folder):
        # the nearest listed folder at or above this one (tests/backend -> tests)
        f = folder
        while f and f not in table:
            f = f.rsplit('/', 1)[0] if '/' in f else ''
        return f or None

    problems = []
    checked = 0
    for dirpath, dirnames, filenames in os.walk(root):
        rel_dir = os.path.relpath(dirpath, root).replace(os.sep, '/')
        dirnames[:] = [d for d in dirnames
                       if d not in SKIP and not d.startswith('.') and not (rel_dir == '.' and d.startswith('build'))]
        for name in filenames:
            if not name.endswith(SOURCES):
                continue
            rel = (rel_dir + '/' + name) if rel_dir != '.' else name
            layer = row(rel_dir if rel_dir != '.' else '')
            if layer is None:
                problems.append(f'{rel}: folder {rel_dir} has no line in the layers table')
                continue
            allowed = table[layer]
            checked += 1
            text = open(os.path.join(dirpath, name), encoding='utf-8', errors='replace').read()
            for inc in INCLUDE.findall(text):
                if '/' not in inc:
                    continue  # a sibling file ("lbh_reader.h")
                target = row(os.path.dirname(inc))
                if target is None:
                    continue  # not a project folder (a system header in quotes)
                if target == layer or '*' in allowed or target in allowed:
                    continue
                problems.append(f'{rel}: includes "{inc}", but {layer} may include only '
                                f'{", ".join(sorted(allowed)) or "nothing outside itself"}')
    for p in problems:
        print(p)
    if problems:
        print(f'check-layers: {len(problems)} include(s) against the layering of docs/architecture.md')
        return 1
    print(f'check-layers: {checked} files follow the layering of docs/architecture.md')
    return 0


if __name__ == '__main__':
    sys.exit(main())
