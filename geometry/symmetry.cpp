// SPDX-License-Identifier: MIT
#include "geometry/symmetry.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <algorithm>
#include <limits>

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

ModelFrame model_frame(const Points& pts, double min_gain) {
    G2L_CHECK(pts.rows() >= 4, "model_frame: need at least 4 points, got ", pts.rows());
    G2L_CHECK(pts.allFinite(), "model_frame: a model point is not finite");
    G2L_CHECK(std::isfinite(min_gain) && min_gain >= 0 && min_gain < 1,
              "model_frame: min_gain must be in [0, 1), got ", min_gain);
    const Eigen::MatrixXd P = pts.cast<double>();
    const int64_t n = P.rows();
    ModelFrame aligned;
    const Eigen::Vector3d lo = P.colwise().minCoeff(), hi = P.colwise().maxCoeff();
    aligned.centre = (0.5 * (lo + hi)).cast<float>();
    aligned.size = (hi - lo).cast<float>();
    const double vol_aligned = (hi - lo).prod();
    const Eigen::RowVector3d mean = P.colwise().mean();
    const Eigen::MatrixXd C = P.rowwise() - mean;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C.transpose() * C / double(n));
    double best_vol = vol_aligned;
    Eigen::Matrix3d best_axes = Eigen::Matrix3d::Identity();
    for (int k = 0; k < 3; ++k) {
        // The box along principal axis a: turn the cross-section axes (u, v) about a to the
        // least-area rectangle (a rectangle's area is 90-degree periodic in the turn).
        const Eigen::Vector3d a = eig.eigenvectors().col(k).normalized();
        const Eigen::Vector3d u0 = eig.eigenvectors().col((k + 1) % 3).normalized();
        const Eigen::Vector3d v0 = a.cross(u0);
        const Eigen::VectorXd pu = P * u0, pv = P * v0, pa = P * a;
        const double len = pa.maxCoeff() - pa.minCoeff();
        double best_area = std::numeric_limits<double>::infinity(), best_th = 0;
        for (int step = 0; step < 180; ++step) {
            const double th = step * 0.5 * kPi / 180.0, c = std::cos(th), s = std::sin(th);
            double ulo = 1e300, uhi = -1e300, vlo = 1e300, vhi = -1e300;
            for (int64_t i = 0; i < n; ++i) {
                const double x = c * pu[i] + s * pv[i], y = -s * pu[i] + c * pv[i];
                ulo = std::min(ulo, x); uhi = std::max(uhi, x);
                vlo = std::min(vlo, y); vhi = std::max(vhi, y);
            }
            const double area = (uhi - ulo) * (vhi - vlo);
            if (area < best_area) { best_area = area; best_th = th; }
        }
        if (best_area * len < best_vol) {
            best_vol = best_area * len;
            const double c = std::cos(best_th), s = std::sin(best_th);
            best_axes.col(0) = c * u0 + s * v0;
            best_axes.col(1) = -s * u0 + c * v0;
            best_axes.col(2) = a;  // u x v = a: right-handed
        }
    }
    if (!(best_vol < (1.0 - min_gain) * vol_aligned)) return aligned;
    // Each box axis is signed to point along the model axis it is nearest (a stable choice).
    for (int j = 0; j < 3; ++j) {
        int m = 0;
        best_axes.col(j).cwiseAbs().maxCoeff(&m);
        if (best_axes(m, j) < 0) best_axes.col(j) *= -1.0;
    }
    if (best_axes.determinant() < 0) best_axes.col(2) *= -1.0;
    const Eigen::MatrixXd Q = P * best_axes;  // box coordinates
    const Eigen::Vector3d qlo = Q.colwise().minCoeff(), qhi = Q.colwise().maxCoeff();
    ModelFrame f;
    f.axes = best_axes.cast<float>();
    f.centre = (best_axes * (0.5 * (qlo + qhi))).cast<float>();
    f.size = (qhi - qlo).cast<float>();
    f.aligned = false;
    return f;
}

namespace {

// symmetry_score's sums over every stride-th tree point, stopping once the error sum exceeds
// stop_above (the sums only grow: what is left cannot bring the mean back under a bound).
// Returns false when it stopped early.
bool score_sums(const ModelKdTree& tree, const SymmetryTransform& s, int64_t stride,
                double stop_above, double* err, double* moved) {
    const Points& pts = tree.points();
    *err = 0, *moved = 0;
    for (int64_t i = 0; i < pts.rows(); i += stride) {
        if (*err > stop_above) return false;
        const Eigen::Vector3f p = pts.row(i).transpose();
        const Eigen::Vector3f q = s.R * p + s.t;
        *err += tree.nearest(q);
        *moved += (q - p).norm();
    }
    return *err <= stop_above;
}

// The stride of symmetry_score's points: every stride-th tree point, at most max_points.
int64_t score_stride(int64_t n, int max_points) {
    return std::max<int64_t>(1, (n + max_points - 1) / max_points);
}

}  // namespace

SymmetryScore symmetry_score(const ModelKdTree& tree, const SymmetryTransform& s,
                             int max_points) {
    G2L_CHECK(max_points > 0, "symmetry_score: max_points must be > 0, got ", max_points);
    const int64_t n = tree.points().rows();
    const int64_t stride = score_stride(n, max_points);
    const double count = double((n + stride - 1) / stride);
    double err = 0, moved = 0;
    score_sums(tree, s, stride, std::numeric_limits<double>::infinity(), &err, &moved);
    return {err / count, moved / count};
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
    // Candidates are turns of the object's own box: F Rc F^T about its centre.
    const ModelFrame frame = model_frame(tree.points());
    const Eigen::Matrix3f F = frame.axes;
    const Eigen::Vector3f c =
        frame.aligned ? Eigen::Vector3f((info.min + 0.5 * info.size).cast<float>()) : frame.centre;
    if (!frame.aligned)
        for (auto& R : candidates) R = F * R * F.transpose();
    const double tol = opt.tolerance_frac * info.diameter;
    // Each candidate on its own (in parallel; the list keeps the candidates' order), scored as
    // symmetry_score scores it, but rejected as soon as its error sum exceeds tol times the
    // point count (most are, after a small part of the points): the same verdicts, several
    // times faster.
    std::vector<SymmetryTransform> turns(candidates.size());
    for (size_t i = 0; i < candidates.size(); ++i) {
        turns[i].R = candidates[i];
        turns[i].t = c - candidates[i] * c;  // rotate about the box centre
    }
    const int64_t n = tree.points().rows();
    const int64_t stride = score_stride(n, opt.max_points);
    const double count = double((n + stride - 1) / stride);
    std::vector<char> keep(turns.size(), 0);
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t i = 1; i < int64_t(turns.size()); ++i) {
        double err = 0, moved = 0;
        if (!score_sums(tree, turns[size_t(i)], stride, tol * count, &err, &moved)) continue;
        const double e = err / count, d = moved / count;
        keep[size_t(i)] = e <= opt.displacement_frac * d || e <= opt.noise_frac * info.diameter;
    }
    std::vector<SymmetryTransform> out(1);  // identity
    for (size_t i = 1; i < turns.size(); ++i)
        if (keep[i]) out.push_back(turns[i]);
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
