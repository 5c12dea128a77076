#!/usr/bin/env python3
"""mkfilm.py MAIN.pbrt OUT.pbrt [LONG=96]: copy MAIN with the Film's x/yresolution scaled so the
longer side is LONG pixels (aspect kept, rounded); everything else byte-for-byte unchanged.
pbrt-v4's defaults (1280x720) apply when a resolution is absent. Prints 'WxH -> wxh'."""
import re, sys
TOK = re.compile(r'"[^"]*"|\[|\]|#[^\n]*|[^\s\[\]"#]+')
src, dst = sys.argv[1], sys.argv[2]; LONG = int(sys.argv[3]) if len(sys.argv) > 3 else 96
text = open(src, encoding='utf-8', errors='surrogateescape').read()
toks = [(m.group(0), m.start(), m.end()) for m in TOK.finditer(text) if not m.group(0).startswith('#')]
films = [i for i, t in enumerate(toks) if t[0] == 'Film']
if len(films) != 1: sys.exit(f'expected one Film directive, found {len(films)}')
i = films[0] + 2  # skip Film "type"
params = {}
while i < len(toks) and not (toks[i][0][:1].isalpha() and toks[i][0][:1].isupper()):
    t = toks[i][0]
    if t.startswith('"') and len(t[1:-1].split()) == 2:
        name = t[1:-1].split()[1]; j = i + 1
        if toks[j][0] == '[':
            k = j + 1
            while toks[k][0] != ']': k += 1
            vals = toks[j+1:k]; i = k + 1
        else:
            vals = [toks[j]]; i = j + 1
        params[name] = vals
    else:
        i += 1
if 'pixelbounds' in params: sys.exit('Film has pixelbounds; not handled')
def val(name, default):
    return int(float(params[name][0][0])) if name in params else default
X, Y = val('xresolution', 1280), val('yresolution', 720)
s = LONG / max(X, Y); x, y = max(1, round(X * s)), max(1, round(Y * s))
edits = []  # (start, end, replacement)
insert = ''
for name, v in (('xresolution', x), ('yresolution', y)):
    if name in params:
        tok = params[name][0]; edits.append((tok[1], tok[2], str(v)))
    else:
        insert += f' "integer {name}" [ {v} ]'
if insert:
    t = toks[films[0] + 1]; edits.append((t[2], t[2], insert))
for a, b, r in sorted(edits, reverse=True):
    text = text[:a] + r + text[b:]
open(dst, 'w', encoding='utf-8', errors='surrogateescape').write(text)
print(f'{X}x{Y} -> {x}x{y}')
