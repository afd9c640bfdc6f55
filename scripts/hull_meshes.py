"""Write the convex hull of each mesh a MuJoCo model names, as small binary STL files.

MuJoCo collides with a mesh's convex hull, not with the mesh itself, so a model whose meshes are
replaced by their hulls has the same contacts; its inertias come from the model's <inertial>
elements, not from the meshes. A robot's published meshes weigh tens of megabytes (the G1's:
20 MB); their hulls, of at most ``--max-vertices`` vertices each (the hull's vertices thinned by
farthest-point sampling, as MuJoCo's own ``maxhullvert`` thins a hull: an inner approximation,
within a few millimetres of the full hull on a robot's links), weigh a few hundred kilobytes,
small enough to ship in a robot profile. Only the look changes (renders show the hulls).

    python scripts/hull_meshes.py MODEL.xml SOURCE_MESH_DIR OUT_DIR [--max-vertices 128]
        [--substitute MISSING=PRESENT ...]

``--substitute`` names a mesh to hull in place of one the source lacks (a mesh missing from a
snapshot of the robot's repository; say so in the profile).
"""
from __future__ import annotations

import argparse
import struct
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

_HEADER = struct.Struct('<80sI')
_TRIANGLE = np.dtype([('normal', '<f4', 3), ('vertices', '<f4', (3, 3)), ('attribute', '<u2')])


def read_stl(path: Path) -> np.ndarray:
    """The vertices (n, 3) of a binary or ASCII STL file."""
    data = path.read_bytes()
    if len(data) >= _HEADER.size:
        _, count = _HEADER.unpack_from(data)
        if _HEADER.size + count * _TRIANGLE.itemsize == len(data):
            triangles = np.frombuffer(data, _TRIANGLE, count, _HEADER.size)
            return triangles['vertices'].reshape(-1, 3).astype(float)
    words = data.decode('ascii', errors='replace').split()
    values = [float(w) for i, w in enumerate(words[:-3]) if words[i - 1] == 'vertex'
              or (i >= 2 and words[i - 2] == 'vertex') or (i >= 3 and words[i - 3] == 'vertex')]
    if not values:
        raise ValueError(f'{path}: not an STL file')
    return np.array(values).reshape(-1, 3)


def thinned_hull_points(vertices: np.ndarray, max_vertices: int) -> tuple[np.ndarray, float]:
    """At most ``max_vertices`` of the hull's vertices, spread by farthest-point sampling, and
    how far [m] the dropped hull vertices lie outside their hull (the approximation's error)."""
    points = vertices[ConvexHull(vertices).vertices]
    if len(points) <= max_vertices:
        return points, 0.0
    chosen = [int(np.argmax(np.linalg.norm(points - points.mean(axis=0), axis=1)))]
    distance = np.linalg.norm(points - points[chosen[0]], axis=1)
    while len(chosen) < max_vertices:
        chosen.append(int(np.argmax(distance)))
        distance = np.minimum(distance, np.linalg.norm(points - points[chosen[-1]], axis=1))
    kept = points[chosen]
    hull = ConvexHull(kept)
    # Signed distance of every original hull vertex to the thinned hull's faces (outside: > 0).
    outside = (points @ hull.equations[:, :3].T + hull.equations[:, 3]).max(axis=1)
    return kept, float(max(outside.max(), 0.0))


def write_hull_stl(vertices: np.ndarray, path: Path) -> int:
    """Write the convex hull of ``vertices`` as a binary STL; returns its triangle count."""
    hull = ConvexHull(vertices)
    triangles = np.zeros(len(hull.simplices), _TRIANGLE)
    centre = vertices[hull.vertices].mean(axis=0)
    for k, simplex in enumerate(hull.simplices):
        a, b, c = vertices[simplex]
        normal = np.cross(b - a, c - a)
        if normal @ (a - centre) < 0.0:             # outward, counter-clockwise seen from outside
            b, c, normal = c, b, -normal
        triangles[k]['normal'] = normal / max(np.linalg.norm(normal), 1e-12)
        triangles[k]['vertices'] = (a, b, c)
    path.write_bytes(_HEADER.pack(b'convex hull (scripts/hull_meshes.py)', len(triangles))
                     + triangles.tobytes())
    return len(triangles)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('model', type=Path, help='the MuJoCo model (MJCF) naming the meshes')
    parser.add_argument('source', type=Path, help='the folder of the published meshes')
    parser.add_argument('out', type=Path, help='where to write the hulls')
    parser.add_argument('--substitute', action='append', default=[], metavar='MISSING=PRESENT')
    parser.add_argument('--max-vertices', type=int, default=128)
    args = parser.parse_args(argv)
    substitutes = dict(s.split('=', 1) for s in args.substitute)
    args.out.mkdir(parents=True, exist_ok=True)
    for mesh in ET.parse(args.model).getroot().iter('mesh'):
        name = mesh.get('file')
        source = args.source / substitutes.get(name, name)
        if not source.is_file() or source.stat().st_size == 0:
            print(f'{name}: missing in {args.source} (give --substitute)', file=sys.stderr)
            return 1
        points, error_m = thinned_hull_points(read_stl(source), args.max_vertices)
        triangles = write_hull_stl(points, args.out / name)
        print(f'{name}: {source.stat().st_size} bytes -> hull of {triangles} triangles, within '
              f'{error_m * 1000:.1f} mm of the full hull'
              + (f' (from {source.name})' if source.name != name else ''))
    return 0


if __name__ == '__main__':
    raise SystemExit(main(sys.argv[1:]))
