#!/usr/bin/env python3
"""The folders show the design: no folder holds more than 20 ideas side by side (a .cpp and its .h
are one), no two files include each other, a module's folders include only themselves and the
folders below them, and every file's opening comment is at most 15 lines.
  check_folders.py SOURCE_DIR"""
import collections, os, re, sys

MAX_IDEAS, MAX_OPENING = 20, 15
# Inside a module, the order its folders stand in: a folder includes only those before it.
LAYERS = {
    'merge': ['base', 'cost', 'boxes', 'top', 'engine', ''],
    'io': ['files', 'format', 'shape', 'mesh', 'write', 'read', 'cut', 'verify', ''],
    'grid': ['stages', 'job', ''],
}
LIBRARY = ['stream', 'merge', 'storage', 'io', 'grid', 'query', 'picture', 'generate', 'tiles', 'cli', 'python/src', 'include']

root = sys.argv[1]
os.chdir(root)
failed = []
sources = []
for top in LIBRARY:
    for d, _, names in os.walk(top):
        sources += [os.path.join(d, n) for n in names if re.search(r'\.(cpp|h)$', n)]

ideas = collections.defaultdict(set)
for s in sources:
    ideas[os.path.dirname(s)].add(os.path.splitext(os.path.basename(s))[0])
for folder, names in sorted(ideas.items()):
    if len(names) > MAX_IDEAS:
        failed.append(f'{folder}: {len(names)} files side by side (at most {MAX_IDEAS})')

include = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
def resolve(source, name):
    module = source.split('/')[0]
    for base in (os.path.dirname(source), module, '.', 'include'):
        p = os.path.normpath(os.path.join(base, name))
        if os.path.isfile(p): return p
    return None

def idea(path):  # a .cpp and its .h are one
    return os.path.splitext(path)[0]

edges = collections.defaultdict(set)
for s in sources:
    text = open(s, encoding='utf-8').read()
    lines = text.split('\n')
    opening = 0
    while opening < len(lines) and lines[opening].startswith('//'): opening += 1
    if opening > MAX_OPENING:
        failed.append(f'{s}: an opening comment of {opening} lines (at most {MAX_OPENING})')
    for name in include.findall(text):
        target = resolve(s, name)
        if not target: continue
        if idea(target) != idea(s): edges[idea(s)].add(idea(target))
        module = s.split('/')[0]
        if module in LAYERS and target.startswith(module + '/'):
            def layer(p):
                parts = p.split('/')
                return LAYERS[module].index(parts[1] if len(parts) > 2 else '')
            if layer(target) > layer(s):
                failed.append(f'{s}: includes {target}, a folder above its own')
for a, targets in sorted(edges.items()):
    for b in sorted(targets):
        if a < b and a in edges.get(b, ()):
            failed.append(f'{a} and {b} include each other')

for f in failed: print(f, file=sys.stderr)
if not failed:
    print(f'folders: at most {MAX_IDEAS} files side by side, no include cycle, layers one way, '
          f'openings of at most {MAX_OPENING} lines')
sys.exit(1 if failed else 0)
