// SPDX-License-Identifier: MIT
#include "data/render_primitives.h"

#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "core/error.h"

namespace g2l::data {

geom::Mesh make_box(double sx, double sy, double sz) {
    G2L_CHECK(sx > 0 && sy > 0 && sz > 0, "make_box: edge lengths must be > 0, got sx=", sx,
              " sy=", sy, " sz=", sz);
    geom::Mesh m;
    m.path = "<box>";
    m.vertices.resize(8, 3);
    for (int i = 0; i < 8; ++i) {  // bit 0: x, bit 1: y, bit 2: z
        m.vertices(i, 0) = float((i & 1 ? 0.5 : -0.5) * sx);
        m.vertices(i, 1) = float((i & 2 ? 0.5 : -0.5) * sy);
        m.vertices(i, 2) = float((i & 4 ? 0.5 : -0.5) * sz);
    }
    // Two triangles per side, counter-clockwise seen from outside.
    const int f[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6},   // z-, z+
                          {0, 1, 5}, {0, 5, 4}, {2, 6, 7}, {2, 7, 3},   // y-, y+
                          {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};  // x-, x+
    m.faces.resize(12, 3);
    for (int i = 0; i < 12; ++i) {
        for (int k = 0; k < 3; ++k) m.faces(i, k) = f[i][k];
    }
    return m;
}

geom::Mesh make_icosphere(double radius, int subdivisions) {
    G2L_CHECK(radius > 0, "make_icosphere: radius must be > 0, got ", radius);
    // Each level multiplies the triangles by 4; 7 levels already give 20 * 4^7 = 327,680.
    G2L_CHECK(subdivisions >= 0 && subdivisions <= 7,
              "make_icosphere: subdivisions must be in [0, 7], got ", subdivisions);
    // The regular icosahedron's vertices are the cyclic permutations of (0, +-1, +-g), g the
    // golden ratio; they are put on the unit sphere and scaled by `radius` at the end.
    const double g = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<Eigen::Vector3d> v = {{-1, g, 0}, {1, g, 0},  {-1, -g, 0}, {1, -g, 0},
                                      {0, -1, g}, {0, 1, g},  {0, -1, -g}, {0, 1, -g},
                                      {g, 0, -1}, {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
    for (auto& p : v) p.normalize();
    std::vector<std::array<int, 3>> f = {
        {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
        {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int s = 0; s < subdivisions; ++s) {
        // One midpoint per edge, shared by the two triangles on it: the mesh stays watertight with
        // no duplicated vertices. minmax makes (a, b) and (b, a) the same edge.
        std::map<std::pair<int, int>, int> mid;
        auto midpoint = [&](int a, int b) {
            const auto key = std::minmax(a, b);
            const auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            v.push_back((v[size_t(a)] + v[size_t(b)]).normalized());
            mid.emplace(key, int(v.size()) - 1);
            return int(v.size()) - 1;
        };
        std::vector<std::array<int, 3>> next;
        next.reserve(f.size() * 4);
        for (const auto& t : f) {
            const int a = midpoint(t[0], t[1]), b = midpoint(t[1], t[2]), c = midpoint(t[2], t[0]);
            // The four children keep the parent's winding, so the faces stay counter-clockwise from
            // outside.
            next.push_back({t[0], a, c});
            next.push_back({t[1], b, a});
            next.push_back({t[2], c, b});
            next.push_back({a, b, c});
        }
        f.swap(next);
    }
    geom::Mesh m;
    m.path = "<icosphere>";
    m.vertices.resize(Eigen::Index(v.size()), 3);
    m.normals.resize(Eigen::Index(v.size()), 3);
    for (size_t i = 0; i < v.size(); ++i) {
        m.vertices.row(Eigen::Index(i)) = (v[i] * radius).cast<float>().transpose();
        // On a sphere the unit position is the exact normal.
        m.normals.row(Eigen::Index(i)) = v[i].cast<float>().transpose();
    }
    m.faces.resize(Eigen::Index(f.size()), 3);
    for (size_t i = 0; i < f.size(); ++i) {
        for (int k = 0; k < 3; ++k) m.faces(Eigen::Index(i), k) = f[i][size_t(k)];
    }
    return m;
}

geom::Mesh make_quad(double size, int n) {
    G2L_CHECK(size > 0, "make_quad: size must be > 0, got ", size);
    G2L_CHECK(n >= 1 && n <= 256, "make_quad: cells per side must be in [1, 256], got ", n);
    geom::Mesh m;
    m.path = "<quad>";
    const int nv = n + 1;
    m.vertices.resize(nv * nv, 3);
    for (int j = 0; j < nv; ++j) {
        for (int i = 0; i < nv; ++i) {
            m.vertices.row(j * nv + i) << float(size * (double(i) / n - 0.5)),
                float(size * (double(j) / n - 0.5)), 0.0f;
        }
    }
    m.faces.resize(2 * n * n, 3);
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            const int a = j * nv + i, b = a + 1, c = a + nv, d = c + 1;
            // Counter-clockwise seen from +z, so the normal is +z as documented.
            m.faces.row(2 * (j * n + i)) << a, b, d;
            m.faces.row(2 * (j * n + i) + 1) << a, d, c;
        }
    }
    return m;
}

}  // namespace g2l::data
