// SPDX-License-Identifier: MIT
#include "geometry/kabsch.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <cmath>

#include "core/error.h"

namespace g2l::geom {

// G2L recovers rotations this way twice (spec §1 steps 8-9): block B's keypoints -> R, then
// R * corners + block C's residuals -> the final Rg.
Eigen::Matrix3d rotation_from_covariance(const Eigen::Matrix3d& H) {
    // JacobiSVD is the accurate choice for a 3 x 3 and stays orthogonal for rank-deficient H
    // (collinear or coplanar points); fixed-size matrices need the Full (not Thin) U and V.
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Matrix3d& U = svd.matrixU();
    const Eigen::Matrix3d& V = svd.matrixV();
    // d corrects a reflection; the smallest singular value (last column) takes the sign flip.
    // The standard reflection fix of spec §7; the released G2L code negates a column of V^T
    // instead, which does not give the nearest proper rotation.
    const double d = (V * U.transpose()).determinant() < 0 ? -1.0 : 1.0;
    return V * Eigen::Vector3d(1, 1, d).asDiagonal() * U.transpose();
}

namespace {

template <class Pts>
void check_pair(const Pts& P, const Pts& Q, const char* fn) {
    G2L_CHECK(P.rows() == Q.rows(), fn, ": P has ", P.rows(), " points but Q has ", Q.rows());
    // Fewer than 3 pairs cannot pin down a rotation.
    G2L_CHECK(P.rows() >= 3, fn, ": need at least 3 point pairs, got ", P.rows());
    for (Eigen::Index i = 0; i < P.rows(); ++i) {
        // A single NaN would pass silently through the SVD into R.
        G2L_CHECK(P.row(i).allFinite() && Q.row(i).allFinite(), fn, ": row ", i,
                  " is not finite: P=(", P.row(i), ") Q=(", Q.row(i), ")");
    }
}

/// Weighted means and cross-covariance; w == nullptr means all weights 1.
template <class Pts>
Pose solve(const Pts& P, const Pts& Q, const std::vector<double>* w) {
    const Eigen::Index n = P.rows();
    double wsum = 0;
    Eigen::Vector3d pm = Eigen::Vector3d::Zero(), qm = Eigen::Vector3d::Zero();
    for (Eigen::Index i = 0; i < n; ++i) {
        const double wi = w ? (*w)[i] : 1.0;
        wsum += wi;
        // Accumulated in double even for float points (centroids of hundreds of mm-sized values).
        pm += wi * P.row(i).template cast<double>().transpose();
        qm += wi * Q.row(i).template cast<double>().transpose();
    }
    pm /= wsum;
    qm /= wsum;
    // Centring both sets first separates rotation from translation; t follows from the means.
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    for (Eigen::Index i = 0; i < n; ++i) {
        const double wi = w ? (*w)[i] : 1.0;
        H += wi * (P.row(i).template cast<double>().transpose() - pm) *
             (Q.row(i).template cast<double>() - qm.transpose());
    }
    Pose pose;
    pose.R = rotation_from_covariance(H);
    pose.t = qm - pose.R * pm;
    return pose;
}

void check_weights(const std::vector<double>& w, Eigen::Index n) {
    G2L_CHECK(static_cast<Eigen::Index>(w.size()) == n, "kabsch: got ", w.size(),
              " weights for ", n, " points");
    double sum = 0;
    for (size_t i = 0; i < w.size(); ++i) {
        G2L_CHECK(std::isfinite(w[i]) && w[i] >= 0, "kabsch: weight ", i,
                  " must be finite and >= 0, got ", w[i]);
        sum += w[i];
    }
    G2L_CHECK(sum > 0, "kabsch: weights sum to ", sum, " (need > 0)");
}

}  // namespace

Eigen::Matrix3d kabsch(const Points& P, const Points& Q) {
    check_pair(P, Q, "kabsch");
    return solve(P, Q, nullptr).R;
}

Eigen::Matrix3d kabsch(const Points& P, const Points& Q, const std::vector<double>& weights) {
    check_pair(P, Q, "kabsch");
    check_weights(weights, P.rows());
    return solve(P, Q, &weights).R;
}

Pose kabsch_pose(const Points& P, const Points& Q) {
    check_pair(P, Q, "kabsch_pose");
    return solve(P, Q, nullptr);
}

Pose kabsch_pose(const Points& P, const Points& Q, const std::vector<double>& weights) {
    check_pair(P, Q, "kabsch_pose");
    check_weights(weights, P.rows());
    return solve(P, Q, &weights);
}

Eigen::Matrix3d kabsch(const PointsD& P, const PointsD& Q) {
    check_pair(P, Q, "kabsch");
    return solve(P, Q, nullptr).R;
}

Pose kabsch_pose(const PointsD& P, const PointsD& Q) {
    check_pair(P, Q, "kabsch_pose");
    return solve(P, Q, nullptr);
}

void kabsch_batched(const float* P, const float* Q, int B, int K, float* R_out) {
    G2L_CHECK(B >= 0, "kabsch_batched: B must be >= 0, got ", B);
    G2L_CHECK(K >= 3, "kabsch_batched: need K >= 3 keypoints per item, got ", K);
    if (B == 0) return;
    G2L_CHECK(P != nullptr && Q != nullptr && R_out != nullptr,
              "kabsch_batched: null buffer (P=", static_cast<const void*>(P), " Q=",
              static_cast<const void*>(Q), " R_out=", static_cast<const void*>(R_out), ")");
    const int64_t n = int64_t(B) * K * 3;
    // Validated before the parallel loop: an exception must not escape an OpenMP region (it
    // would terminate the process).
    for (int64_t i = 0; i < n; ++i) {
        G2L_CHECK(std::isfinite(P[i]) && std::isfinite(Q[i]), "kabsch_batched: non-finite value "
                  "at b=", i / (int64_t(K) * 3), " k=", (i / 3) % K, " (P=", P[i], " Q=", Q[i],
                  ")");
    }
    // One item per iteration, independent of the others: no cross-thread sums.
#pragma omp parallel for schedule(static)
    for (int b = 0; b < B; ++b) {
        const float* p = P + int64_t(b) * K * 3;
        const float* q = Q + int64_t(b) * K * 3;
        Eigen::Vector3d pm = Eigen::Vector3d::Zero(), qm = Eigen::Vector3d::Zero();
        for (int k = 0; k < K; ++k) {
            pm += Eigen::Vector3d(p[3 * k], p[3 * k + 1], p[3 * k + 2]);
            qm += Eigen::Vector3d(q[3 * k], q[3 * k + 1], q[3 * k + 2]);
        }
        pm /= K;
        qm /= K;
        Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
        for (int k = 0; k < K; ++k) {
            const Eigen::Vector3d pc = Eigen::Vector3d(p[3 * k], p[3 * k + 1], p[3 * k + 2]) - pm;
            const Eigen::Vector3d qc = Eigen::Vector3d(q[3 * k], q[3 * k + 1], q[3 * k + 2]) - qm;
            H += pc * qc.transpose();
        }
        const Eigen::Matrix3d R = rotation_from_covariance(H);
        float* r = R_out + int64_t(b) * 9;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) r[3 * i + j] = static_cast<float>(R(i, j));
        }
    }
}

}  // namespace g2l::geom
