#!/usr/bin/env python3
"""List the files a pbrt-v4 scene reads (recursing into Include/Import) and whether each exists.
Usage: scanrefs.py MAIN.pbrt  -> lines 'OK|MISSING <kind> <path relative to the main file's dir>'
kind: include | ply | image | normalmap | bsdf | spectrum | other.  The Film's output filename is skipped."""
import gzip, os, re, sys
TOK = re.compile(rb'"[^"]*"|\[|\]|#[^\n]*|[^\s\[\]"#]+')
def read(p):
    with open(p, 'rb') as f:
        b = f.read()
    return gzip.decompress(b) if p.endswith('.gz') else b
def kind_of(p):
    l = p.lower()
    if re.search(r'\.pbrt(\.gz)?$', l): return 'include'
    if re.search(r'\.ply(\.gz)?$', l): return 'ply'
    if re.search(r'\.(png|exr|tga|pfm|hdr|jpg|jpeg|tif|tiff|bmp|qoi|ptx)$', l): return 'image'
    if l.endswith('.bsdf'): return 'bsdf'
    if l.endswith('.spd') or l.endswith('.csv') or l.endswith('.txt'): return 'spectrum'
    return 'other'
def refs_in(b):
    """yield file names referenced in one file's bytes"""
    toks = [t for t in TOK.findall(b) if not t.startswith(b'#')]
    directive = None; i = 0; n = len(toks)
    while i < n:
        t = toks[i]
        if t[:1].isalpha() and t[:1].isupper():
            directive = t.decode()
            if directive in ('Include', 'Import') and i + 1 < n and toks[i+1].startswith(b'"'):
                yield (toks[i+1][1:-1].decode('utf-8', 'replace'), False); i += 2; continue
        elif t.startswith(b'"') and b' ' in t.strip(b'"').strip():
            parts = t[1:-1].split()
            if len(parts) == 2:
                ty, name = parts[0].decode(), parts[1].decode()
                # values: one string or [ strings ]
                vals = []; j = i + 1
                if j < n and toks[j] == b'[':
                    j += 1
                    while j < n and toks[j] != b']':
                        vals.append(toks[j]); j += 1
                elif j < n:
                    vals.append(toks[j])
                svals = [v[1:-1].decode('utf-8', 'replace') for v in vals if v.startswith(b'"')]
                if ty == 'string' and name in ('filename', 'normalmap', 'lensfile') and directive != 'Film':
                    for v in svals: yield (v, name == 'normalmap')
                elif ty == 'spectrum':
                    for s in svals:
                        if '.' in s or '/' in s: yield (s, False)
        i += 1
def main():
    mainf = os.path.abspath(sys.argv[1]); base = os.path.dirname(mainf)
    seen = {}; todo = [mainf]
    while todo:
        f = todo.pop()
        for rel, nmap in refs_in(read(f)):
            p = rel if os.path.isabs(rel) else os.path.normpath(os.path.join(base, rel))
            if p in seen: continue
            ok = os.path.isfile(p); seen[p] = (ok, nmap)
            if ok and kind_of(p) == 'include': todo.append(p)
    for p, (ok, nmap) in sorted(seen.items()):
        k = 'normalmap' if nmap and kind_of(p) == 'image' else kind_of(p)
        print(('OK ' if ok else 'MISSING ') + k + ' ' + os.path.relpath(p, base))
main()
