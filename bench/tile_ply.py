#!/usr/bin/env python3
"""Tiles a binary little-endian PLY NX x NZ times on the x-z plane over a ground quad.

The large model of README "Large models on lavapipe" (issue 16):
  penumbra generate scan --triangles 70000 -o statue.ply
  bench/tile_ply.py statue.ply statues.ply 12 13     # 10,920,002 triangles
  penumbra preprocess statues.ply -o statues.penumbra
Input: float x y z vertices, faces as a uchar count and uint indices (what
`penumbra generate` writes). Copies are 1.25 model widths apart; the quad lies
at the model's lowest y. Written to a temporary name, then renamed.
"""
import struct, sys
from array import array

if len(sys.argv) != 5 or not sys.argv[3].isdigit() or not sys.argv[4].isdigit() or int(sys.argv[3]) < 1 or int(sys.argv[4]) < 1:
    sys.exit('usage: tile_ply.py IN.ply OUT.ply NX NZ (NX, NZ >= 1)')
src, out, nx, nz = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
try:
    data = open(src, 'rb').read()
except OSError as e:
    sys.exit('%s: cannot read (%s)' % (src, e.strerror))
expected = ('format binary_little_endian 1.0', 'property float x', 'property float y', 'property float z',
            'property list uchar uint vertex_indices')
head = data[:data.find(b'end_header\n')].decode('ascii', 'replace') if b'end_header\n' in data else ''
if not head.startswith('ply') or any(line not in head for line in expected) or head.count('property') != 4:
    sys.exit('%s: not a binary little-endian PLY of float x y z vertices and uchar/uint faces (what penumbra generate writes)' % src)
end = data.index(b'end_header\n') + len(b'end_header\n')
header = data[:end].decode()
nv = int(header.split('element vertex ')[1].split()[0])
nf = int(header.split('element face ')[1].split()[0])
if len(data) != end + 12 * nv + 13 * nf:
    sys.exit('%s: %d bytes, expected %d for %d vertices and %d triangles' % (src, len(data), end + 12 * nv + 13 * nf, nv, nf))
pos = array('f'); pos.frombytes(data[end:end + 12 * nv])
faces = []
off = end + 12 * nv
for i in range(nf):
    a, b, c = struct.unpack_from('<3I', data, off + 1); off += 13
    faces.append((a, b, c))
xs, ys, zs = pos[0::3], pos[1::3], pos[2::3]
lo = (min(xs), min(ys), min(zs)); hi = (max(xs), max(ys), max(zs))
sx, sz = 1.25 * (hi[0] - lo[0]), 1.25 * (hi[2] - lo[2])
copies = nx * nz
tv, tf = nv * copies + 4, nf * copies + 2
with open(out + '.tmp', 'wb') as f:
    f.write(('ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n'
             'element face %d\nproperty list uchar uint vertex_indices\nend_header\n' % (tv, tf)).encode())
    for i in range(nx):
        for k in range(nz):
            dx, dz = (i - (nx - 1) / 2) * sx, (k - (nz - 1) / 2) * sz
            moved = array('f', pos)
            for j in range(0, 3 * nv, 3):
                moved[j] += dx; moved[j + 2] += dz
            f.write(moved.tobytes())
    gx, gz, gy = nx * sx * 0.6, nz * sz * 0.6, lo[1]
    f.write(array('f', [-gx, gy, -gz, gx, gy, -gz, gx, gy, gz, -gx, gy, gz]).tobytes())
    face = struct.Struct('<B3I')
    for c in range(copies):
        base = c * nv
        f.write(b''.join(face.pack(3, a + base, b + base, cc + base) for a, b, cc in faces))
    g = nv * copies
    f.write(face.pack(3, g, g + 2, g + 1) + face.pack(3, g, g + 3, g + 2))
import os; os.replace(out + '.tmp', out)
print('bounds of one', lo, hi, '->', tv, 'vertices', tf, 'triangles')
