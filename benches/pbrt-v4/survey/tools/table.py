#!/usr/bin/env python3
"""Builds $SURVEY_DIR/table.md (and out/means.json) from $SURVEY_DIR/out/{pbrt,kiln}/<scene>.{exr,log,time}.
Env (run.sh sets them): SURVEY_DIR (required), SPP, LONG, TIMEOUT (only quoted in the text)."""
import json, os, sys
HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the survey's script folder
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, HERE)
from exrmean import stats
S = os.environ.get('SURVEY_DIR') or sys.exit('set SURVEY_DIR')
SPP, LONG, TIMEOUT = (os.environ.get(k, d) for k, d in (('SPP', '256'), ('LONG', '96'), ('TIMEOUT', '1200')))
scenes = [l.split('\t')[0] for l in open(f'{HERE}/scenes.tsv') if l.strip()]
# pbrt-v4 means of the survey before this one (same settings): a check on the pbrt-v4 build and stand-ins
PREV = {'cornell-box': (0.1864, 0.1229, 0.03443), 'bathroom': (2.557, 2.553, 2.541),
        'kitchen': (1.27, 1.248, 1.239), 'crown': (0.4003, 0.2483, 0.1458),
        'sssdragon': (0.828, 0.7628, 0.7176), 'kroken': (1.081, 1.014, 0.9873)}
g = lambda x: '%.4g' % x
def info(r, n):
    d = {'exr': f'{S}/out/{r}/{n}.exr', 'time': None, 'rc': None, 'err': None, 'stats': None}
    t = f'{S}/out/{r}/{n}.time'
    if os.path.exists(t):
        rc, secs = open(t).read().split(); d['rc'], d['time'] = int(rc), float(secs)
    if os.path.exists(d['exr']) and d['rc'] == 0:
        try: d['stats'] = stats(d['exr'])
        except Exception as e: d['err'] = f'cannot read output: {e}'
    elif d['rc'] is not None:
        log = f'{S}/out/{r}/{n}.log'
        lines = [l.rstrip() for l in open(log, errors='replace')] if os.path.exists(log) else []
        lines = [l for l in lines if l.strip()]
        why = f'timed out after {TIMEOUT} s' if d['rc'] == 124 else f'exit {d["rc"]}'
        d['err'] = why + ': ' + ' | '.join(lines[-3:])[-400:]
    return d
rows, fails, out = [], [], {}
both = 0
for n in scenes:
    p, k = info('pbrt', n), info('kiln', n)
    out[n] = {'pbrt': p, 'kiln': k}
    pm = p['stats']['mean'] if p['stats'] else None
    km = k['stats']['mean'] if k['stats'] else None
    cell = lambda m: ' '.join(g(x) for x in m) if m else '—'
    if pm and km:
        both += 1
        rs = []
        for a, b in zip(km, pm):
            if b == 0: rs.append('**inf**' if a else 'n/a'); continue
            q = a / b; s = g(q); rs.append(f'**{s}**' if not (0.98 <= q <= 1.02) else s)
        ratio = ' '.join(rs)
    else:
        ratio = '—'
    tm = lambda d: ('%.0f' % d['time']) if d['time'] is not None else '—'
    nf = []
    for r, d in (('pbrt', p), ('Kiln', k)):
        if d['stats'] and d['stats']['nonfinite']: nf.append(f"{r}: {d['stats']['nonfinite']} non-finite px")
    if pm and km and max(pm) == 0 and max(km) == 0: nf.append('all-black image in both')
    res = f"{p['stats']['width']}x{p['stats']['height']}" if p['stats'] else (f"{k['stats']['width']}x{k['stats']['height']}" if k['stats'] else '')
    rows.append(f"| {n} | {res} | {cell(pm)} | {cell(km)} | {ratio} | {tm(p)} | {tm(k)} | {'; '.join(nf)} |")
    for r, d in (('pbrt-v4', p), ('Kiln', k)):
        if d['err']: fails.append(f'- {n} ({r}): {d["err"]}')
os.makedirs(f'{S}/out', exist_ok=True)
json.dump(out, open(f'{S}/out/means.json', 'w'), indent=1)
binfo = open(f'{S}/out/kiln/BINARY.txt').read().strip().replace('\n', '; ') if os.path.exists(f'{S}/out/kiln/BINARY.txt') else '?'
L = ['# Kiln vs pbrt-v4: per-channel means', '',
     f'{len(scenes)} renders; {both} rendered by both. Film longer side {LONG} px, {SPP} spp, 2 threads, seed 0 '
     '(pbrt `--seed 0`, Kiln default), sampler/integrator/maxdepth as in each file; Kiln spectral (default). '
     'Means over all pixels with finite R, G, B (non-finite pixels counted in the last column). '
     'Ratios outside [0.98, 1.02] in bold. Times are wall-clock seconds including scene loading, '
     'both renderers at `nice -n 19`, so only as comparable as the machine was quiet.', '',
     f'Kiln binary: {binfo}', '',
     '| scene | res | pbrt-v4 R G B | Kiln R G B | Kiln/pbrt R G B | pbrt s | Kiln s | notes |',
     '|---|---|---|---|---|---|---|---|'] + rows
L += ['', '## Failures', ''] + (fails or ['none'])
L += ['', '## pbrt-v4 against the previous survey', '', '| scene | previous pbrt R G B | now pbrt R G B | now/previous |', '|---|---|---|---|']
for n, pv in PREV.items():
    st = out[n]['pbrt']['stats']
    if st:
        m = st['mean']; L.append(f"| {n} | {' '.join(g(x) for x in pv)} | {' '.join(g(x) for x in m)} | {' '.join(g(a/b) for a, b in zip(m, pv))} |")
    else:
        L.append(f"| {n} | {' '.join(g(x) for x in pv)} | — | — |")
open(f'{S}/table.md', 'w').write('\n'.join(L) + '\n')
print('\n'.join(L))
