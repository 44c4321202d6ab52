// SPDX-License-Identifier: MIT
// Small procedural meshes for the renderer: the support plane of synthetic scenes, benchmark
// scenes and analytic tests. All lengths in millimetres; faces wind counter-clockwise seen from
// outside (outward normals), so back-face culling keeps the outside.
#pragma once

#include "geometry/types.h"

namespace g2l::data {

/// Axis-aligned box centred at the origin with edge lengths sx, sy, sz (mm): 8 vertices,
/// 12 triangles. Throws g2l::Error when an edge length is not > 0 (naming it).
geom::Mesh make_box(double sx, double sy, double sz);

/// Icosphere of `radius` mm centred at the origin: the icosahedron with each triangle split into
/// 4 `subdivisions` times (20 * 4^s triangles, vertices pushed onto the sphere). Throws
/// g2l::Error when radius <= 0 or subdivisions is not in [0, 7].
geom::Mesh make_icosphere(double radius, int subdivisions);

/// Square in the plane z = 0 with side `size` mm centred at the origin, split into n x n cells
/// (2 n^2 triangles), normal +z. Throws g2l::Error when size <= 0 or n is not in [1, 256].
geom::Mesh make_quad(double size, int n);

}  // namespace g2l::data
