#!/usr/bin/env python3
"""Writes the fuzz_fch seed corpus: small cluster files made with the facetree CLI (both box
precisions; the v1_ seeds beside them were written by the version 1 writer), and copies
of them whose zstd frames hold one stored (raw) block each, so that fuzz_fch's mutations of
the payload bytes stay decompressible (it recomputes the checksums before reading).

usage: make_fch_seeds.py FACETREE_CLI OUT_DIR     (needs the zstd command line tool)
"""
import os
import struct
import subprocess
import sys
import tempfile

MASK = (1 << 64) - 1
P1, P2, P3, P4, P5 = (0x9E3779B185EBCA87, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                      0x85EBCA77C2B2AE63, 0x27D4EB2F165667C5)


def rotl(x, r):
    return ((x << r) | (x >> (64 - r))) & MASK


def xxh64(data, seed=0):
    def rnd(acc, lane):
        return (rotl((acc + lane * P2) & MASK, 31) * P1) & MASK

    def merge(acc, val):
        return ((acc ^ rnd(0, val)) * P1 + P4) & MASK

    n, i = len(data), 0
    if n >= 32:
        v = [(seed + P1 + P2) & MASK, (seed + P2) & MASK, seed, (seed - P1) & MASK]
        while i + 32 <= n:
            for k in range(4):
                v[k] = rnd(v[k], struct.unpack_from('<Q', data, i + 8 * k)[0])
            i += 32
        h = (rotl(v[0], 1) + rotl(v[1], 7) + rotl(v[2], 12) + rotl(v[3], 18)) & MASK
        for k in range(4):
            h = merge(h, v[k])
    else:
        h = (seed + P5) & MASK
    h = (h + n) & MASK
    while i + 8 <= n:
        h = (rotl(h ^ rnd(0, struct.unpack_from('<Q', data, i)[0]), 27) * P1 + P4) & MASK
        i += 8
    if i + 4 <= n:
        h = (rotl(h ^ (struct.unpack_from('<I', data, i)[0] * P1 & MASK), 23) * P2 + P3) & MASK
        i += 4
    while i < n:
        h = (rotl(h ^ (data[i] * P5 & MASK), 11) * P1) & MASK
        i += 1
    h = ((h ^ (h >> 33)) * P2) & MASK
    h = ((h ^ (h >> 29)) * P3) & MASK
    return h ^ (h >> 32)


def stored_frame(raw):
    """One zstd frame: single segment, 4-byte content size, raw blocks of at most 128 KiB."""
    out = bytearray(struct.pack('<IB', 0xFD2FB528, (2 << 6) | (1 << 5)))
    out += struct.pack('<I', len(raw))
    for start in range(0, max(len(raw), 1), 1 << 17):
        block = raw[start:start + (1 << 17)]
        last = start + (1 << 17) >= len(raw)
        out += struct.pack('<I', (len(block) << 3) | int(last))[:3] + block
    return bytes(out)


def with_stored_frames(fch):
    header = bytearray(fch[:192])
    frames = struct.unpack_from('<I', header, 56)[0]
    index = bytearray(fch[192:192 + 40 * frames])
    body = bytearray()
    offset = 192 + 40 * frames
    for i in range(frames):
        e = 40 * i
        old_offset, compressed = struct.unpack_from('<QI', index, e + 16)
        raw = subprocess.run(['zstd', '-d', '-c'], input=fch[old_offset:old_offset + compressed],
                             check=True, capture_output=True).stdout
        frame = stored_frame(raw)
        struct.pack_into('<QIIQ', index, e + 16, offset, len(frame), len(raw), xxh64(frame))
        body += frame
        offset += len(frame)
    struct.pack_into('<Q', header, 16, offset)
    struct.pack_into('<Q', header, 120, xxh64(bytes(index)))
    struct.pack_into('<Q', header, 184, xxh64(bytes(header[:184])))
    return bytes(header + index + body)


def main():
    cli, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        def run(*args):
            subprocess.run([cli, *args], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

        def t(name):
            return os.path.join(tmp, name)
        run('gen', 'sphere', '-n', '200', '-o', t('sphere.ply'))
        run('gen', 'grid', '-n', '40', '-o', t('grid.ply'))
        run('gen', 'terrain', '-n', '64', '-o', t('terrain.ply'))
        run('build', t('sphere.ply'), '-o', t('sphere.fch'))
        run('build', t('grid.ply'), '-o', t('grid_b4.fch'), '--branching', '4')
        run('build', t('terrain.ply'), '-o', t('terrain_b8.fch'), '--branching', '8', '--recast', 'fewest-nodes',
            '--metric', 'garland')
        run('truncate', t('sphere.fch'), '-o', t('sphere_trunc.fch'), '--nodes', '20')
        run('build', t('sphere.ply'), '-o', t('sphere_compact.fch'), '--boxes', 'compact')
        run('build', t('grid.ply'), '-o', t('grid_b4_compact.fch'), '--branching', '4', '--boxes', 'compact')
        run('truncate', t('sphere_compact.fch'), '-o', t('sphere_compact_trunc.fch'), '--nodes', '20')
        for name in ['sphere', 'grid_b4', 'terrain_b8', 'sphere_trunc', 'sphere_compact', 'grid_b4_compact',
                     'sphere_compact_trunc']:
            data = open(t(name + '.fch'), 'rb').read()
            open(os.path.join(out, name + '.fch'), 'wb').write(data)
            stored = with_stored_frames(data)
            if len(stored) <= 20000:  # seeds stay small (the full sphere stored is ~22 KB)
                open(os.path.join(out, name + '_stored.fch'), 'wb').write(stored)


if __name__ == '__main__':
    main()
