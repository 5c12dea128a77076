#!/usr/bin/env python3
"""exrmean.py FILE.exr [...] -> per file: 'file W H meanR meanG meanB nonfinite'
Means are over all pixels whose R, G and B are all finite; 'nonfinite' counts the pixels where any
of R, G, B is NaN or infinite (those are left out of the means). --json prints a JSON list instead."""
import json, sys
import numpy as np
import OpenEXR

def rgb(path):
    with OpenEXR.File(path, separate_channels=True) as f:
        ch = f.channels()
        names = list(ch)
        def pick(c):
            for n in (c, c.lower()):
                if n in ch: return ch[n].pixels.astype(np.float64)
            # layered names like 'Beauty.R' or 'rgb.R'
            for n in names:
                if n.split('.')[-1] in (c, c.lower()): return ch[n].pixels.astype(np.float64)
            raise KeyError(f'{path}: no {c} channel (has {names})')
        return np.stack([pick('R'), pick('G'), pick('B')], axis=-1)

def stats(path):
    a = rgb(path)
    h, w = a.shape[:2]
    ok = np.isfinite(a).all(axis=-1)
    m = a[ok].mean(axis=0) if ok.any() else np.full(3, np.nan)
    return {'file': path, 'width': w, 'height': h, 'mean': [float(x) for x in m],
            'nonfinite': int((~ok).sum())}

if __name__ == '__main__':
    args = [a for a in sys.argv[1:] if a != '--json']
    res = [stats(p) for p in args]
    if '--json' in sys.argv: print(json.dumps(res))
    else:
        for r in res:
            print(r['file'], r['width'], r['height'], *('%.6g' % x for x in r['mean']), r['nonfinite'])
