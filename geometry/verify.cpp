// SPDX-License-Identifier: MIT
#include "geometry/verify.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace g2l::geom {

Verification verify_pose(const ModelKdTree& tree, const ModelInfo& info, const Pose& pose,
                         const DepthImage& depth, const Points& object_points,
                         const VerifyOptions& opt, const ClosestPointGrid* grid) {
    const Intrinsics& K = depth.K;
    G2L_CHECK(depth.depth_mm != nullptr && K.width > 0 && K.height > 0,
              "verify_pose: need a depth image and its size, got ", K.width, " x ", K.height);
    G2L_CHECK(std::isfinite(info.diameter) && info.diameter > 0,
              "verify_pose: model diameter must be > 0, got ", info.diameter);
    G2L_CHECK(pose.R.allFinite() && pose.t.allFinite(), "verify_pose: the pose is not finite");
    G2L_CHECK(opt.tol_frac >= 0 && opt.tol_min_mm > 0 && opt.model_points >= 1 &&
                  opt.object_points >= 0 && opt.violation_weight >= 0 &&
                  opt.occluded_weight >= 0 && opt.min_visible >= 1 && opt.footprint_cell_px >= 1,
              "verify_pose: options out of range (tol_frac ", opt.tol_frac, ", tol_min_mm ",
              opt.tol_min_mm, ", model_points ", opt.model_points, ", object_points ",
              opt.object_points, ", weights ", opt.violation_weight, " / ", opt.occluded_weight,
              ", min_visible ", opt.min_visible, ", footprint_cell_px ", opt.footprint_cell_px, ")");
    Verification v;
    v.tol_mm = std::max(opt.tol_min_mm, opt.tol_frac * info.diameter);
    const float tol = float(v.tol_mm);
    const Points& mp = tree.points();
    const int64_t n_tree = mp.rows();
    const int64_t n = std::min<int64_t>(n_tree, opt.model_points);
    if (n == 0 || !(pose.t.z() > 1.0)) return v;  // behind the camera: nothing visible

    // 1. Project the (strided) surface points. The tree holds the vertices plus samples ~2 mm
    //    apart (ModelKdTree::from_mesh), so n of them lie ~2 sqrt(n_tree / n) mm apart; the
    //    z-buffer's cells span about two such gaps in the image so every cell the model covers
    //    holds a front point.
    const Eigen::Matrix3f R = pose.R.cast<float>();
    const Eigen::Vector3f t = pose.t.cast<float>();
    struct Proj {
        float z;
        int u, v;
    };
    std::vector<Proj> proj(static_cast<size_t>(n));
    int u0 = std::numeric_limits<int>::max(), v0 = u0, u1 = std::numeric_limits<int>::min(),
        v1 = u1;
    for (int64_t i = 0; i < n; ++i) {
        const Eigen::Vector3f q = R * mp.row(i * n_tree / n).transpose() + t;
        Proj& p = proj[size_t(i)];
        p.z = q.z();
        if (!(q.z() > 1.f)) {
            p.u = -1;
            continue;
        }
        // Tested in floating point before the cast: a far-off point must not overflow an int.
        const double uf = std::floor(K.fx * q.x() / q.z() + K.cx);
        const double vf = std::floor(K.fy * q.y() / q.z() + K.cy);
        if (!(uf >= 0 && vf >= 0 && uf < K.width && vf < K.height)) {
            p.u = -1;
            continue;
        }
        p.u = int(uf);
        p.v = int(vf);
        u0 = std::min(u0, p.u), u1 = std::max(u1, p.u);
        v0 = std::min(v0, p.v), v1 = std::max(v1, p.v);
    }
    if (u0 > u1) return v;  // nothing in the image
    const double spacing_mm = 2.0 * std::sqrt(double(n_tree) / double(n));
    const double px = std::max(K.fx, K.fy) * spacing_mm / pose.t.z();
    const int cell = std::clamp(int(std::ceil(2.0 * px)), 1, 32);
    const int cw = (u1 - u0) / cell + 1, ch = (v1 - v0) / cell + 1;
    std::vector<float> zbuf(size_t(cw) * size_t(ch), std::numeric_limits<float>::infinity());
    auto cell_of = [&](const Proj& p) {
        return size_t((p.v - v0) / cell) * size_t(cw) + size_t((p.u - u0) / cell);
    };
    for (const Proj& p : proj)
        if (p.u >= 0) zbuf[cell_of(p)] = std::min(zbuf[cell_of(p)], p.z);

    // 2. Each visible point against the depth at its pixel.
    int bu0 = K.width, bu1 = -1, bv0 = K.height, bv1 = -1;  // the inliers' pixels
    const int fc = opt.footprint_cell_px;
    const int fw = (K.width + fc - 1) / fc;
    for (const Proj& p : proj) {
        if (p.u < 0 || p.z > zbuf[cell_of(p)] + tol) continue;  // hidden by the model itself
        // The 3 x 3 pixels around the point: a point on the silhouette falls a fraction of a
        // pixel off the surface that holds it (and real sensors blur edges), so the depth
        // explains it when any of them does, and it is seen through only when all of them lie
        // behind it.
        int measured = 0;
        bool near = false, nearer = false;
        for (int dv = -1; dv <= 1; ++dv)
            for (int du = -1; du <= 1; ++du) {
                const int uu = p.u + du, vv = p.v + dv;
                if (uu < 0 || vv < 0 || uu >= K.width || vv >= K.height) continue;
                const float d = depth.depth_mm[size_t(vv) * size_t(K.width) + size_t(uu)];
                if (!(d > 0.f) || !std::isfinite(d)) continue;
                ++measured;
                near = near || std::abs(d - p.z) <= tol;
                nearer = nearer || d < p.z - tol;
            }
        const float dc = depth.depth_mm[size_t(p.v) * size_t(K.width) + size_t(p.u)];
        if (!(dc > 0.f) || !std::isfinite(dc) || measured == 0) {
            ++v.unmeasured;
            continue;
        }
        ++v.visible;
        if (!near && !nearer) {
            ++v.violations;
        } else if (!near) {
            ++v.occluded;
        } else {
            ++v.inliers;
            v.footprint.push_back(int32_t((p.v / fc) * fw + p.u / fc));
            bu0 = std::min(bu0, p.u), bu1 = std::max(bu1, p.u);
            bv0 = std::min(bv0, p.v), bv1 = std::max(bv1, p.v);
        }
    }
    if (v.inliers >= opt.min_visible) v.box = {bu0, bv0, bu1 - bu0 + 1, bv1 - bv0 + 1};
    std::sort(v.footprint.begin(), v.footprint.end());
    v.footprint.erase(std::unique(v.footprint.begin(), v.footprint.end()), v.footprint.end());

    // 3. The segmentation's object points against the posed surface (model frame).
    const int64_t no = object_points.rows();
    const int64_t m = std::min<int64_t>(no, opt.object_points);
    int agree = 0, counted = 0;
    const Eigen::Matrix3f Rt = R.transpose();
    for (int64_t i = 0; i < m; ++i) {
        const Eigen::Vector3f x = object_points.row(i * no / m).transpose();
        if (!x.allFinite()) continue;
        ++counted;
        const Eigen::Vector3f y = Rt * (x - t);
        if (grid) {  // the nearest model point when one lies within the tolerance (else none)
            int idx = 0;
            agree += grid->nearest_below(y, tol * (1.f + 1e-5f) + 1e-6f, &idx) <= tol;
        } else {
            agree += tree.nearest(y) <= tol;
        }
    }
    v.seg_agree = counted ? double(agree) / double(counted) : 0.0;

    if (v.visible > 0) {
        v.explained = double(v.inliers) / v.visible;
        v.violation = double(v.violations) / v.visible;
        v.occlusion = double(v.occluded) / v.visible;
        const double denom = v.inliers + opt.violation_weight * v.violations +
                             opt.occluded_weight * v.occluded;
        v.support = denom > 0 ? v.inliers / denom : 0.0;
    }
    v.score = v.visible >= opt.min_visible ? v.support * v.seg_agree : 0.0;
    return v;
}

double footprint_overlap(const std::vector<int32_t>& a, const std::vector<int32_t>& b) {
    if (a.empty() || b.empty()) return 0.0;
    size_t i = 0, j = 0, common = 0;
    while (i < a.size() && j < b.size()) {
        if (a[i] < b[j]) {
            ++i;
        } else if (b[j] < a[i]) {
            ++j;
        } else {
            ++common, ++i, ++j;
        }
    }
    return double(common) / double(b.size());
}

}  // namespace g2l::geom
