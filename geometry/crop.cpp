// SPDX-License-Identifier: MIT
#include "geometry/crop.h"

#include <cmath>

#include "core/error.h"

namespace g2l::geom {
namespace {

/// Indices i with keep(i), ascending. The mask is filled in parallel; the compaction is serial,
/// so the output is the same for any thread count.
template <class Keep>
std::vector<int> select(const Points& pts, Keep keep) {
    const int64_t n = pts.rows();
    std::vector<uint8_t> mask(static_cast<size_t>(n));
#pragma omp parallel for schedule(static) if (n > 20000)
    for (int64_t i = 0; i < n; ++i) mask[i] = keep(i) ? 1 : 0;
    std::vector<int> out;
    for (int64_t i = 0; i < n; ++i) {
        if (mask[i]) out.push_back(static_cast<int>(i));
    }
    return out;
}

}  // namespace

std::vector<int> crop_sphere(const Points& pts, const Eigen::Vector3d& centre, double radius) {
    G2L_CHECK(std::isfinite(radius) && radius > 0, "crop_sphere: radius must be finite and > 0, "
              "got ", radius);
    G2L_CHECK(centre.allFinite(), "crop_sphere: centre is not finite: (", centre.transpose(), ")");
    const double r2 = radius * radius;
    return select(pts, [&](int64_t i) {
        return (pts.row(i).cast<double>() - centre.transpose()).squaredNorm() < r2;
    });
}

std::vector<int> crop_slab(const Points& pts, double centre_z, double half_depth) {
    G2L_CHECK(std::isfinite(half_depth) && half_depth > 0, "crop_slab: half_depth must be finite "
              "and > 0, got ", half_depth);
    G2L_CHECK(std::isfinite(centre_z), "crop_slab: centre_z is not finite (", centre_z, ")");
    return select(pts, [&](int64_t i) { return std::abs(pts(i, 2) - centre_z) < half_depth; });
}

std::vector<int> crop_slab_adaptive(const Points& pts, double centre_z, double diameter,
                                    const AdaptiveSlabParams& params, int* factor_used) {
    G2L_CHECK(std::isfinite(diameter) && diameter > 0, "crop_slab_adaptive: diameter must be "
              "finite and > 0, got ", diameter);
    G2L_CHECK(std::isfinite(centre_z), "crop_slab_adaptive: centre_z is not finite (", centre_z,
              ")");
    auto slab = [&](double half) {
        return select(pts, [&](int64_t i) {
            const double z = pts(i, 2);
            return z > params.min_z && std::abs(z - centre_z) < half;
        });
    };
    int factor = 1;
    std::vector<int> kept = slab(diameter);
    if (static_cast<int64_t>(kept.size()) < params.min_points_2dia) {
        factor = 2;
        kept = slab(2 * diameter);
        if (static_cast<int64_t>(kept.size()) < params.min_points_3dia) {
            factor = 3;
            kept = slab(3 * diameter);
        }
    }
    if (factor_used) *factor_used = factor;
    return kept;
}

}  // namespace g2l::geom
