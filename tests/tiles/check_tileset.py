#!/usr/bin/env python3
"""Checks a 3D Tiles 1.1 tileset as the official validator does where it matters to a viewer, and
its levels of detail as facetree promises them; prints a JSON summary, exits 1 naming the first
failure.
  - every content URI exists; external tilesets are followed (their root stands for the linking
    tile, with the same box and geometric error);
  - geometric errors strictly decrease from parent to child, and leaf tiles' are 0;
  - every glb is well formed (header, chunk lengths, accessors' min and max, indices in range);
  - every tile's vertices lie inside its own box and every ancestor's (spatial coherence);
  - no box has a zero axis.
  check_tileset.py DIR [--triangles N]   (N: the leaves must hold exactly N triangles)"""
import json
import os
import struct
import sys

import numpy as np


class Invalid(Exception):
    pass


def read_glb(path):
    data = open(path, 'rb').read()
    if len(data) < 20:
        raise Invalid(f'{path}: shorter than a glb header')
    magic, version, length = struct.unpack_from('<4sII', data, 0)
    if magic != b'glTF' or version != 2 or length != len(data):
        raise Invalid(f'{path}: header {magic!r} version {version} length {length} of {len(data)} bytes')
    json_length, json_type = struct.unpack_from('<II', data, 12)
    if json_type != 0x4E4F534A or json_length % 4:
        raise Invalid(f'{path}: the first chunk is not a padded JSON chunk')
    gltf = json.loads(data[20:20 + json_length])
    offset = 20 + json_length
    binary = b''
    if offset < len(data):
        bin_length, bin_type = struct.unpack_from('<II', data, offset)
        if bin_type != 0x004E4942 or bin_length % 4 or offset + 8 + bin_length != len(data):
            raise Invalid(f'{path}: the second chunk is not a padded BIN chunk ending the file')
        binary = data[offset + 8:offset + 8 + bin_length]
    primitive = gltf['meshes'][0]['primitives'][0]
    if primitive.get('mode', 4) != 4:
        raise Invalid(f'{path}: not triangles')
    position = gltf['accessors'][primitive['attributes']['POSITION']]
    indices = gltf['accessors'][primitive['indices']]
    draco = 'KHR_draco_mesh_compression' in primitive.get('extensions', {})
    translation = np.array(gltf['nodes'][0].get('translation', [0, 0, 0]), np.float64)
    triangles = indices['count'] // 3
    if draco:  # positions are not decoded here; the accessor's box stands for them
        local = np.array([position['min'], position['max']], np.float64)
    else:
        def view(accessor, dtype, width):
            v = gltf['bufferViews'][accessor['bufferView']]
            start = v.get('byteOffset', 0) + accessor.get('byteOffset', 0)
            return np.frombuffer(binary, dtype, accessor['count'] * width, start)
        local32 = view(position, np.float32, 3).reshape(-1, 3)
        if not (np.array_equal(local32.min(0), np.float32(position['min'])) and
                np.array_equal(local32.max(0), np.float32(position['max']))):
            raise Invalid(f'{path}: POSITION min/max differ from its data')
        index = view(indices, {5121: np.uint8, 5123: np.uint16, 5125: np.uint32}[indices['componentType']], 1)
        if index.size and int(index.max()) >= position['count']:
            raise Invalid(f'{path}: an index past the vertices')
        local = local32.astype(np.float64)
    world = translation + local  # glTF's y up ...
    world = np.stack([world[:, 0], -world[:, 2], world[:, 1]], 1)  # ... turned to 3D Tiles' z up
    return world, triangles, draco


def inside(points, box, what):
    box = np.array(box, np.float64)
    centre, axes = box[:3], box[3:].reshape(3, 3)
    lengths = np.einsum('ij,ij->i', axes, axes)
    if np.any(lengths <= 0):
        raise Invalid(f'{what}: a box with a zero axis')
    reach = np.abs((points - centre) @ axes.T) / lengths  # in units of each half-axis
    worst = float(reach.max()) if reach.size else 0.0
    if worst > 1 + 1e-9:
        raise Invalid(f'{what}: a vertex {worst:.9g} half-axes from the centre')


def check(root_dir, triangles=None):
    summary = {'tiles': 0, 'leaf_tiles': 0, 'levels': 0, 'triangles': 0, 'leaf_triangles': 0,
               'bytes': 0, 'leaf_bytes': 0, 'json_files': 0, 'largest_json': 0, 'draco': False}

    def load(path):
        if not os.path.isfile(path):
            raise Invalid(f'{path}: a content URI that does not exist')
        summary['json_files'] += 1
        summary['largest_json'] = max(summary['largest_json'], os.path.getsize(path))
        tileset = json.load(open(path))
        if tileset['asset']['version'] != '1.1':
            raise Invalid(f'{path}: asset version {tileset["asset"]["version"]}')
        if not tileset['geometricError'] >= tileset['root']['geometricError']:
            raise Invalid(f'{path}: the tileset\'s geometric error is below its root\'s')
        return tileset['root']

    def walk(tile, base, ancestors, depth, parent_error, name):
        content = tile.get('content', {}).get('uri')
        if content and content.endswith('.json'):  # an external tileset: its root stands for this tile
            path = os.path.join(base, content)
            root = load(path)
            if root['boundingVolume'] != tile['boundingVolume'] or root['geometricError'] != tile['geometricError']:
                raise Invalid(f'{path}: its root differs from the tile that links it')
            if tile.get('children'):
                raise Invalid(f'{name}: a tile with an external tileset has children')
            return walk(root, os.path.dirname(path), ancestors, depth, parent_error, content)
        error = tile['geometricError']
        if parent_error is not None and not error < parent_error:
            raise Invalid(f'{name}: geometric error {error} not below its parent\'s {parent_error}')
        box = tile['boundingVolume']['box']
        children = tile.get('children', [])
        summary['tiles'] += 1
        summary['levels'] = max(summary['levels'], depth)
        if content:
            path = os.path.join(base, content)
            if not os.path.isfile(path):
                raise Invalid(f'{path}: a content URI that does not exist')
            world, count, draco = read_glb(path)
            summary['draco'] |= draco
            size = os.path.getsize(path)
            summary['triangles'] += count
            summary['bytes'] += size
            for b in ancestors + [box]:
                if not draco:  # Draco's positions are not decoded here
                    inside(world, b, path)
            if not children:
                summary['leaf_triangles'] += count
                summary['leaf_bytes'] += size
        if not children:
            summary['leaf_tiles'] += 1
            if error != 0:
                raise Invalid(f'{name}: a leaf tile of geometric error {error}')
        for i, child in enumerate(children):
            walk(child, base, ancestors + [box], depth + 1, error, f'{name}/{i}')

    walk(load(os.path.join(root_dir, 'tileset.json')), root_dir, [], 1, None, 'root')
    if triangles is not None and summary['leaf_triangles'] != triangles:
        raise Invalid(f'the leaves hold {summary["leaf_triangles"]} triangles, the file {triangles}')
    return summary


if __name__ == '__main__':
    expected = int(sys.argv[sys.argv.index('--triangles') + 1]) if '--triangles' in sys.argv else None
    try:
        print(json.dumps(check(sys.argv[1], expected)))
    except Invalid as e:
        print(f'check_tileset: {e}', file=sys.stderr)
        sys.exit(1)
