// SPDX-License-Identifier: MIT
// Mesh readers and writer: PLY (ASCII, binary little-endian) and Wavefront OBJ. Units are
// whatever the file holds (BOP models: millimetres); nothing is rescaled.
#pragma once

#include <string>

#include "geometry/types.h"

namespace g2l::geom {

/// Loads a mesh, choosing the reader from the file extension (case-insensitive): ".ply" ->
/// load_ply, ".obj" -> load_obj. Throws g2l::Error naming the path for any other extension and
/// for every error of the chosen reader.
Mesh load_mesh(const std::string& path);

/// Reads a PLY file in `ascii 1.0` or `binary_little_endian 1.0` format.
/// Vertex element: x, y, z (float or double, required); optional nx, ny, nz (all three) and
/// red, green, blue (uchar 0..255, or float/double in 0..1 scaled by 255; alpha is ignored).
/// Face element: `property list <count type> <int|uint> vertex_indices` (or `vertex_index`);
/// polygons with n > 3 corners are fan-triangulated (a quad becomes 2 triangles). Any other
/// property or element is skipped using its declared type size. Returns vertices N x 3, normals
/// N x 3 or empty, colors N x 3 or empty, faces F x 3 (indices into vertices), path = `path`.
/// Throws g2l::Error naming the file for: a missing/unreadable file, a bad or incomplete header,
/// big-endian data (unsupported), an unknown property type, missing x/y/z, truncated data, a
/// malformed ASCII number, a face with fewer than 3 corners, or a face index out of range.
Mesh load_ply(const std::string& path);

/// Reads a Wavefront OBJ file: `v x y z` (extra values such as w or colours are ignored) and
/// `f` records whose corners may be written `a`, `a/b`, `a//c` or `a/b/c`; indices are 1-based,
/// or negative (relative to the vertices read so far). Polygons are fan-triangulated. vn, vt, o,
/// g, s, usemtl, mtllib and comments are ignored (normals and colours stay empty).
/// Throws g2l::Error naming the file and line for a missing file, a malformed number, a face
/// with fewer than 3 corners, or an index of 0 or out of range.
Mesh load_obj(const std::string& path);

/// Writes `mesh` as binary little-endian PLY: vertex x, y, z float; nx, ny, nz float if
/// mesh.normals is non-empty; red, green, blue uchar if mesh.colors is non-empty; faces as
/// `list uchar int vertex_indices`. Throws g2l::Error if normals/colors have a row count other
/// than the vertex count, a face index is out of range, or the file cannot be written.
void save_ply(const std::string& path, const Mesh& mesh);

}  // namespace g2l::geom
