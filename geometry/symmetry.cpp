// SPDX-License-Identifier: MIT
#include "geometry/symmetry.h"

#include <Eigen/Geometry>
#include <cmath>
#include <algorithm>

#include "core/error.h"
#include "geometry/metrics.h"

namespace g2l::geom {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The 24 proper rotations that permute the coordinate axes (with signs): the rotation group of
// the cube. Identity first.
std::vector<Eigen::Matrix3f> axis_permutations() {
    std::vector<Eigen::Matrix3f> out;
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (const auto& p : perms)
        for (int s = 0; s < 8; ++s) {
            Eigen::Matrix3f R = Eigen::Matrix3f::Zero();
            for (int r = 0; r < 3; ++r) R(r, p[r]) = (s >> r) & 1 ? -1.f : 1.f;
            if (R.determinant() > 0) out.push_back(R);
        }
    return out;
}

bool same(const Eigen::Matrix3f& a, const Eigen::Matrix3f& b) {
    return (a - b).cwiseAbs().maxCoeff() < 1e-4f;
}

}  // namespace

SymmetryScore symmetry_score(const ModelKdTree& tree, const SymmetryTransform& s,
                             int max_points) {
    G2L_CHECK(max_points > 0, "symmetry_score: max_points must be > 0, got ", max_points);
    const Points& pts = tree.points();
    const int64_t n = pts.rows();
    const int64_t stride = std::max<int64_t>(1, (n + max_points - 1) / max_points);
    double err = 0, moved = 0;
    int64_t count = 0;
    for (int64_t i = 0; i < n; i += stride) {
        const Eigen::Vector3f p = pts.row(i).transpose();
        const Eigen::Vector3f q = s.R * p + s.t;
        err += tree.nearest(q);
        moved += (q - p).norm();
        ++count;
    }
    return {err / double(count), moved / double(count)};
}

std::vector<SymmetryTransform> geometric_symmetries(const ModelKdTree& tree, const ModelInfo& info,
                                                    const SymmetryOptions& opt) {
    G2L_CHECK(std::isfinite(info.diameter) && info.diameter > 0,
              "geometric_symmetries: model diameter must be > 0, got ", info.diameter);
    G2L_CHECK(std::isfinite(opt.tolerance_frac) && opt.tolerance_frac > 0 &&
                  opt.tolerance_frac < 1,
              "geometric_symmetries: tolerance_frac must be in (0, 1), got ", opt.tolerance_frac);
    G2L_CHECK(std::isfinite(opt.displacement_frac) && opt.displacement_frac > 0 &&
                  opt.displacement_frac < 1,
              "geometric_symmetries: displacement_frac must be in (0, 1), got ",
              opt.displacement_frac);
    G2L_CHECK(std::isfinite(opt.noise_frac) && opt.noise_frac >= 0 && opt.noise_frac < 1,
              "geometric_symmetries: noise_frac must be in [0, 1), got ", opt.noise_frac);
    G2L_CHECK(opt.axis_steps >= 1 && opt.axis_steps <= 3600,
              "geometric_symmetries: axis_steps must be in [1, 3600], got ", opt.axis_steps);
    G2L_CHECK(opt.max_points > 0, "geometric_symmetries: max_points must be > 0, got ",
              opt.max_points);
    std::vector<Eigen::Matrix3f> candidates = axis_permutations();
    for (int axis = 0; axis < 3; ++axis)
        for (int k = 1; k < opt.axis_steps; ++k) {
            const float a = float(2.0 * kPi * k / opt.axis_steps);
            const Eigen::Matrix3f R =
                Eigen::AngleAxisf(a, Eigen::Vector3f::Unit(axis)).toRotationMatrix();
            bool dup = false;
            for (const auto& c : candidates) dup = dup || same(c, R);
            if (!dup) candidates.push_back(R);
        }
    const Eigen::Vector3f c = (info.min + 0.5 * info.size).cast<float>();
    const double tol = opt.tolerance_frac * info.diameter;
    std::vector<SymmetryTransform> out(1);  // identity
    for (size_t i = 1; i < candidates.size(); ++i) {
        SymmetryTransform s;
        s.R = candidates[i];
        s.t = c - s.R * c;  // rotate about the box centre
        const SymmetryScore sc = symmetry_score(tree, s, opt.max_points);
        if (sc.error_mm <= tol && (sc.error_mm <= opt.displacement_frac * sc.displacement_mm ||
                                   sc.error_mm <= opt.noise_frac * info.diameter))
            out.push_back(s);
    }
    return out;
}

Pose compose(const Pose& gt, const SymmetryTransform& s) {
    Pose g;
    g.R = gt.R * s.R.cast<double>();
    g.t = gt.R * s.t.cast<double>() + gt.t;
    return g;
}

double add_sym(const Pose& est, const Pose& gt, const Points& model_pts,
               const std::vector<SymmetryTransform>& syms) {
    double best = add(est, gt, model_pts);
    for (const auto& s : syms) best = std::min(best, add(est, compose(gt, s), model_pts));
    return best;
}

double rotation_error_sym_deg(const Eigen::Matrix3d& R_est, const Eigen::Matrix3d& R_gt,
                              const std::vector<SymmetryTransform>& syms) {
    double best = rotation_error_deg(R_est, R_gt);
    for (const auto& s : syms)
        best = std::min(best, rotation_error_deg(R_est, R_gt * s.R.cast<double>()));
    return best;
}

}  // namespace g2l::geom
