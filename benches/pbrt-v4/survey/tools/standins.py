#!/usr/bin/env python3
"""standins.py SCENEDIR REFS.txt -> creates a stand-in for each MISSING line of REFS.txt (from
scanrefs.py) under SCENEDIR and prints 'path<TAB>what' for each one made.
  8-bit image (png/tga/jpg/...) : 4x4 RGB, all 188 = 0.5 linear after sRGB decoding (normal maps too,
                                  as the previous survey did: the map then tilts normals towards (1,1,1))
  exr                           : 4x4 RGB float32, all 0.5 (linear)
  pfm                           : 4x4 RGB float32, all 0.5
  ply / ply.gz                  : ASCII PLY with one triangle of side 1e-3 at the origin (gzipped for .gz)
  pbrt include                  : empty file
  bsdf (RGL tensor file)        : Lambertian BRDF, reflectance 0.5, 16 theta_i x 32x32 (Kiln's layout)"""
import gzip, math, os, struct, sys, zlib
import numpy as np

def png(path, rgb):
    w = h = 4
    raw = b''.join(b'\x00' + bytes(rgb) * w for _ in range(h))
    def chunk(t, d):
        return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
    data = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 2, 0, 0, 0)) \
        + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b'')
    open(path, 'wb').write(data)

def tga(path, rgb):
    w = h = 4
    hdr = struct.pack('<BBBHHBHHHHBB', 0, 0, 2, 0, 0, 0, 0, 0, w, h, 24, 0)
    open(path, 'wb').write(hdr + bytes([rgb[2], rgb[1], rgb[0]]) * (w * h))

def pfm(path, v):
    open(path, 'wb').write(b'PF\n4 4\n-1.0\n' + np.full((4, 4, 3), v, '<f4').tobytes())

def exr(path, v):
    import OpenEXR
    px = np.full((4, 4, 3), v, np.float32)
    hdr = {'compression': OpenEXR.ZIP_COMPRESSION, 'type': OpenEXR.scanlineimage}
    with OpenEXR.File(hdr, {'RGB': px}) as f:
        f.write(path)

def ply_bytes():
    s = 1e-3
    return (f"ply\nformat ascii 1.0\ncomment survey stand-in\nelement vertex 3\nproperty float x\n"
            f"property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            f"end_header\n0 0 0\n{s} 0 0\n0 {s} 0\n3 0 1 2\n").encode()

def tensor(fields):
    hl = 12 + 2 + 4 + sum(2 + len(n) + 2 + 1 + 8 + 8 * len(sh) for n, (dt, sh, b) in fields)
    out = bytearray(b'tensor_file\0' + bytes([1, 0]) + struct.pack('<I', len(fields)))
    off = hl
    for n, (dt, sh, b) in fields:
        out += struct.pack('<H', len(n)) + n.encode() + struct.pack('<HBQ', len(sh), dt, off)
        out += b''.join(struct.pack('<Q', k) for k in sh)
        off += len(b)
    for n, (dt, sh, b) in fields:
        out += b
    return bytes(out)

def lambertian_bsdf(rho=0.5, nt=16, n=32):
    F32, U8 = 10, 1
    theta_i = np.array([(k / (nt - 1)) ** 2 * math.pi / 2 for k in range(nt)], np.float32)
    ux = np.arange(n, dtype=np.float32) / (n - 1)
    tm = (ux * ux * math.pi / 2)[None, :]            # x -> theta_m
    pm = ((2 * ux - 1) * math.pi)[:, None]           # y -> phi_m
    wm = np.stack([np.sin(tm) * np.cos(pm), np.sin(tm) * np.sin(pm), np.cos(tm) * np.ones_like(pm)])
    r = []
    for to in theta_i:
        wo = np.array([math.sin(to), 0.0, math.cos(to)], np.float32)
        d = wo[0] * wm[0] + wo[1] * wm[1] + wo[2] * wm[2]
        wiz = -wo[2] + 2 * d * wm[2]
        r.append(4.0 / math.pi * np.maximum(wiz, 0))
    r = np.array(r, np.float32)                       # [nt, n, n]
    lum = (r * rho + 0.05)[None]                      # [1, nt, n, n]
    spectra = np.stack([r * rho, r * rho], axis=1)[None]  # [1, nt, 2, n, n]
    f = lambda a: (F32, list(a.shape), np.ascontiguousarray(a, '<f4').tobytes())
    fields = sorted({
        'phi_i': f(np.array([0.0], np.float32)), 'theta_i': f(theta_i),
        'wavelengths': f(np.array([360.0, 830.0], np.float32)),
        'ndf': f(np.ones((n, n), np.float32)), 'sigma': f(np.ones((n, n), np.float32)),
        'vndf': f(np.ones((1, nt, n, n), np.float32)), 'luminance': f(lum), 'spectra': f(spectra),
        'description': (U8, [8], b'stand-in'), 'jacobian': (U8, [1], b'\x01'),
    }.items())
    return tensor(fields)

def make(path, kind):
    os.makedirs(os.path.dirname(path) or '.', exist_ok=True)
    l = path.lower()
    if kind == 'include':
        open(path, 'wb').close(); return 'empty file'
    if kind == 'ply':
        b = ply_bytes()
        if l.endswith('.gz'):
            open(path, 'wb').write(gzip.compress(b, mtime=0)); return 'gzipped PLY, one 1e-3 triangle at origin'
        open(path, 'wb').write(b); return 'PLY, one 1e-3 triangle at origin'
    if kind == 'bsdf':
        open(path, 'wb').write(lambertian_bsdf()); return 'Lambertian RGL tensor, rho 0.5'
    if kind in ('image', 'normalmap'):
        rgb = (188, 188, 188)
        what = ('normal map ' if kind == 'normalmap' else '') + '4x4 mid-grey 188 (0.5 linear)'
        if l.endswith('.png'): png(path, rgb); return 'PNG ' + what
        if l.endswith('.tga'): tga(path, rgb); return 'TGA ' + what
        if l.endswith('.exr'): exr(path, 0.5); return 'EXR 4x4 RGB float 0.5'
        if l.endswith('.pfm'): pfm(path, 0.5); return 'PFM 4x4 RGB float 0.5'
    raise SystemExit(f'no stand-in rule for {path} ({kind})')

scene, refs = sys.argv[1], sys.argv[2]
for line in open(refs):
    st, kind, rel = line.rstrip('\n').split(' ', 2)
    if st != 'MISSING': continue
    p = os.path.join(scene, rel)
    if os.path.exists(p): continue
    print(f'{rel}\t{make(p, kind)}')
