// SPDX-License-Identifier: MIT
// Small helpers shared by the geometry tests: seeded random rotations and point clouds, file
// writers for hand-made fixtures.
#pragma once

#include <Eigen/Geometry>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace g2l::geom::test {

/// Points on the surface of an axis-aligned box of size (sx, sy, sz) centred at `centre` (grid
/// `step` mm), plus, if bump_mm > 0, a solid cube of that size on the +z face at the (+x, +y)
/// corner: a box no rotation maps onto itself.
inline Points box_surface(float sx, float sy, float sz, float step, const Eigen::Vector3f& centre,
                          float bump_mm = 0) {
    std::vector<Eigen::Vector3f> pts;
    const Eigen::Vector3f h(sx / 2, sy / 2, sz / 2);
    for (int axis = 0; axis < 3; ++axis) {
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        for (float a = -h[u]; a <= h[u] + 1e-3f; a += step)
            for (float b = -h[v]; b <= h[v] + 1e-3f; b += step)
                for (float sgn : {-1.f, 1.f}) {
                    Eigen::Vector3f p;
                    p[axis] = sgn * h[axis];
                    p[u] = a;
                    p[v] = b;
                    pts.push_back(p + centre);
                }
    }
    if (bump_mm > 0)
        for (float a = 0; a <= bump_mm; a += step)
            for (float b = 0; b <= bump_mm; b += step)
                for (float c = 0; c <= bump_mm; c += step)
                    pts.push_back(centre + Eigen::Vector3f(h.x() - bump_mm + a, h.y() - bump_mm + b,
                                                           h.z() + c));
    Points out(Eigen::Index(pts.size()), 3);
    for (size_t i = 0; i < pts.size(); ++i) out.row(Eigen::Index(i)) = pts[i].transpose();
    return out;
}

/// Uniform random rotation from a normalised Gaussian quaternion.
inline Eigen::Matrix3d random_rotation(std::mt19937& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
    q.normalize();
    return q.toRotationMatrix();
}

/// N points uniform in [-s, s]^3.
inline Points random_points(int n, double s, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(-s, s);
    Points p(n, 3);
    for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) p(i, c) = static_cast<float>(u(rng));
    }
    return p;
}

/// Writes `text` (or raw bytes) to `path`.
inline void write_file(const std::string& path, const std::string& text) {
    std::ofstream f(path, std::ios::binary);
    f.write(text.data(), static_cast<std::streamsize>(text.size()));
}

/// Appends the raw bytes of a trivially copyable value.
template <class T>
void put(std::string& s, T v) {
    s.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

}  // namespace g2l::geom::test
