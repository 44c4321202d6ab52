// SPDX-License-Identifier: MIT
#include "geometry/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "geometry/labels.h"

namespace g2l::geom {
namespace {

constexpr double kPi = 3.14159265358979323846;

void check_inputs(const Pose& est, const Pose& gt, const Points& pts, const char* fn) {
    G2L_CHECK(pts.rows() > 0, fn, ": no model points");
    G2L_CHECK(est.R.allFinite() && est.t.allFinite(), fn, ": estimated pose is not finite");
    G2L_CHECK(gt.R.allFinite() && gt.t.allFinite(), fn, ": ground-truth pose is not finite");
    G2L_CHECK(pts.allFinite(), fn, ": model points contain NaN or inf");
}

/// pts (N x 3) -> rows R x + t, in double.
Eigen::MatrixXd transform(const Pose& p, const Points& pts) {
    return (pts.cast<double>() * p.R.transpose()).rowwise() + p.t.transpose();
}

/// Mean of per-point values in a fixed order (thread-count independent).
double ordered_mean(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return s / static_cast<double>(v.size());
}

}  // namespace

double add(const Pose& est, const Pose& gt, const Points& model_pts) {
    check_inputs(est, gt, model_pts, "add");
    const Eigen::MatrixXd e = transform(est, model_pts), g = transform(gt, model_pts);
    return (e - g).rowwise().norm().mean();
}

double adds(const Pose& est, const Pose& gt, const Points& model_pts) {
    check_inputs(est, gt, model_pts, "adds");
    const Eigen::MatrixXd e = transform(est, model_pts), g = transform(gt, model_pts);
    const ModelKdTree tree(e.cast<float>());
    const int64_t n = g.rows();
    std::vector<double> d(static_cast<size_t>(n));
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < n; ++i) {
        // Search in float (the tree's type), then measure the found pair in double.
        int j = 0;
        tree.nearest(g.row(i).cast<float>().transpose(), &j);
        d[i] = (g.row(i) - e.row(j)).norm();
    }
    return ordered_mean(d);
}

double rotation_error_deg(const Eigen::Matrix3d& R_est, const Eigen::Matrix3d& R_gt) {
    G2L_CHECK(R_est.allFinite() && R_gt.allFinite(), "rotation_error_deg: non-finite rotation");
    const double c = std::clamp(0.5 * ((R_est * R_gt.transpose()).trace() - 1.0), -1.0, 1.0);
    return std::acos(c) * 180.0 / kPi;
}

double translation_error(const Eigen::Vector3d& t_est, const Eigen::Vector3d& t_gt) {
    G2L_CHECK(t_est.allFinite() && t_gt.allFinite(), "translation_error: non-finite translation "
              "t_est=(", t_est.transpose(), ") t_gt=(", t_gt.transpose(), ")");
    return (t_gt - t_est).norm();
}

bool correct_at(double err, double diameter, double frac) {
    G2L_CHECK(!std::isnan(err), "correct_at: error is NaN (pass +inf for a missed detection)");
    G2L_CHECK(std::isfinite(diameter) && diameter > 0, "correct_at: diameter must be finite and "
              "> 0, got ", diameter);
    G2L_CHECK(std::isfinite(frac) && frac > 0, "correct_at: frac must be finite and > 0, got ",
              frac);
    return err < frac * diameter;
}

double vocap_auc(std::vector<double> distances_m, double max_threshold_m) {
    G2L_CHECK(!distances_m.empty(), "vocap_auc: empty distance list");
    G2L_CHECK(std::isfinite(max_threshold_m) && max_threshold_m > 0,
              "vocap_auc: max_threshold_m must be finite and > 0, got ", max_threshold_m);
    const double inf = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < distances_m.size(); ++i) {
        double& d = distances_m[i];
        G2L_CHECK(!std::isnan(d) && d >= 0, "vocap_auc: distance ", i,
                  " must be >= 0 or +inf, got ", d);
        if (d > max_threshold_m) d = inf;  // D(D > 0.1) = inf
    }
    std::sort(distances_m.begin(), distances_m.end());
    const size_t n = distances_m.size();  // includes the infs
    // Finite prefix of the sorted list, with accuracy (i + 1) / n at entry i.
    std::vector<double> mrec{0.0}, mpre{0.0};
    for (size_t i = 0; i < n && std::isfinite(distances_m[i]); ++i) {
        mrec.push_back(distances_m[i]);
        mpre.push_back(static_cast<double>(i + 1) / static_cast<double>(n));
    }
    if (mrec.size() == 1) return 0.0;  // every entry inf (the MATLAB code would fail here)
    mrec.push_back(max_threshold_m);
    mpre.push_back(mpre.back());
    for (size_t i = 1; i < mpre.size(); ++i) mpre[i] = std::max(mpre[i], mpre[i - 1]);
    // Sum over the indices where the recall axis changes, using the precision at the right end.
    double ap = 0;
    for (size_t i = 1; i < mrec.size(); ++i) {
        if (mrec[i] != mrec[i - 1]) ap += (mrec[i] - mrec[i - 1]) * mpre[i];
    }
    return ap / max_threshold_m * 100.0;
}

double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace g2l::geom
