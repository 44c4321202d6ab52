// SPDX-License-Identifier: MIT
// Small helpers shared by the geometry tests: seeded random rotations and point clouds, file
// writers for hand-made fixtures.
#pragma once

#include <Eigen/Geometry>
#include <fstream>
#include <random>
#include <string>

#include "geometry/types.h"

namespace g2l::geom::test {

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
