# Writes the Mitsuba serialized meshes of this scene (run once; the files are checked in):
#   room.serialized  version 4, two meshes: 0 = floor and two walls (float, uvs, no normals),
#                    1 = a UV sphere (double, normals, uvs and vertex colours, which are skipped)
#   lamp.serialized  version 3, two meshes: 0 = one small triangle (unused), 1 = the ceiling lamp
# The writer follows the format as Mitsuba 3 documents it (src/shapes/serialized.cpp); Mitsuba 3
# reads these files for the reference, so a writer that disagreed with the format would show.
import math, struct, zlib

HAS_NORMALS, HAS_UVS, HAS_COLORS, SINGLE, DOUBLE = 0x1, 0x2, 0x8, 0x1000, 0x2000


def mesh_bytes(version, name, pos, tris, normals=None, uvs=None, colors=None, double=False):
    flags = (DOUBLE if double else SINGLE) | (HAS_NORMALS if normals else 0) | \
        (HAS_UVS if uvs else 0) | (HAS_COLORS if colors else 0)
    f = 'd' if double else 'f'
    body = struct.pack('<I', flags)
    if version == 4:
        body += name.encode() + b'\0'
    body += struct.pack('<QQ', len(pos), len(tris))
    for arr in (pos, normals, uvs, colors):
        if arr:
            body += struct.pack('<%d%s' % (len(arr) * len(arr[0]), f), *[c for v in arr for c in v])
    body += struct.pack('<%dI' % (3 * len(tris)), *[i for t in tris for i in t])
    return struct.pack('<HH', 0x041C, version) + zlib.compress(body)


def write(path, version, meshes):
    data, offsets = b'', []
    for m in meshes:
        offsets.append(len(data))
        data += m
    data += struct.pack('<%d%s' % (len(offsets), 'Q' if version == 4 else 'I'), *offsets)
    data += struct.pack('<I', len(offsets))
    open(path, 'wb').write(data)


def quad(pos, uvs, tris, a, b, c, d):  # corners counter-clockwise seen from the front
    base = len(pos)
    pos += [a, b, c, d]
    uvs += [(0, 0), (1, 0), (1, 1), (0, 1)]
    tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]


room_pos, room_uvs, room_tris = [], [], []
quad(room_pos, room_uvs, room_tris, (-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0))  # floor, +z
quad(room_pos, room_uvs, room_tris, (-2, 2, 0), (2, 2, 0), (2, 2, 3), (-2, 2, 3))  # back, -y
quad(room_pos, room_uvs, room_tris, (-2, -2, 0), (-2, 2, 0), (-2, 2, 3), (-2, -2, 3))  # left, +x

sph_pos, sph_n, sph_uv, sph_col, sph_tris = [], [], [], [], []
nu, nv = 24, 12
for j in range(nv + 1):
    th = math.pi * j / nv
    for i in range(nu + 1):
        ph = 2 * math.pi * i / nu
        n = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
        sph_n.append(n)
        sph_pos.append(tuple(0.5 * c for c in n))
        sph_uv.append((i / nu, j / nv))
        sph_col.append((1.0, 0.0, 0.0))
for j in range(nv):
    for i in range(nu):
        a, b = j * (nu + 1) + i, (j + 1) * (nu + 1) + i
        if j > 0:
            sph_tris.append((a, b, a + 1))
        if j < nv - 1:
            sph_tris.append((a + 1, b, b + 1))

write('room.serialized', 4, [
    mesh_bytes(4, 'room', room_pos, room_tris, uvs=room_uvs),
    mesh_bytes(4, 'ball', sph_pos, sph_tris, normals=sph_n, uvs=sph_uv, colors=sph_col,
               double=True)])
write('lamp.serialized', 3, [
    mesh_bytes(3, '', [(0, 0, 0), (0.01, 0, 0), (0, 0.01, 0)], [(0, 1, 2)]),
    mesh_bytes(3, '', [(-0.5, -0.5, 0), (-0.5, 0.5, 0), (0.5, 0.5, 0), (0.5, -0.5, 0)],
               [(0, 1, 2), (0, 2, 3)])])
