// SPDX-License-Identifier: MIT
#include "geometry/keypoints.h"

#include <limits>
#include <vector>

#include "core/error.h"

namespace g2l::geom {

Points bbox_corners(const ModelInfo& info) {
    G2L_CHECK(info.min.allFinite() && info.size.allFinite(),
              "bbox_corners: models_info min/size must be finite, got min=(",
              info.min.transpose(), ") size=(", info.size.transpose(), ")");
    G2L_CHECK((info.size.array() >= 0).all(), "bbox_corners: models_info size must be >= 0, got (",
              info.size.transpose(), ")");
    const Eigen::Vector3d lo = info.min, hi = info.min + info.size;
    // {x from max?, y from max?, z from max?} per corner, spec §5 order.
    static const int kSel[8][3] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {0, 0, 0},
                                   {1, 0, 0}, {1, 0, 1}, {1, 1, 0}, {1, 1, 1}};
    Points c(8, 3);
    for (int k = 0; k < 8; ++k) {
        for (int a = 0; a < 3; ++a) c(k, a) = static_cast<float>(kSel[k][a] ? hi[a] : lo[a]);
    }
    return c;
}

Points farthest_point_sampling(const Points& pts, int k, int start) {
    const Eigen::Index n = pts.rows();
    G2L_CHECK(k >= 1 && k <= n, "farthest_point_sampling: k must be in [1, ", n, "], got ", k);
    G2L_CHECK(start >= -1 && start < n, "farthest_point_sampling: start must be -1 or in [0, ",
              n, "), got ", start);
    G2L_CHECK(pts.allFinite(), "farthest_point_sampling: input points contain NaN or inf");
    const Eigen::MatrixXd p = pts.cast<double>();
    Eigen::Index first = start;
    if (start < 0) {
        const Eigen::RowVector3d centroid = p.colwise().mean();
        (p.rowwise() - centroid).rowwise().squaredNorm().maxCoeff(&first);  // first max wins
    }
    std::vector<double> dmin(static_cast<size_t>(n), std::numeric_limits<double>::infinity());
    Points out(k, 3);
    Eigen::Index cur = first;
    for (int s = 0; s < k; ++s) {
        out.row(s) = pts.row(cur);
        Eigen::Index next = 0;
        double best = -1;
        for (Eigen::Index i = 0; i < n; ++i) {
            dmin[i] = std::min(dmin[i], (p.row(i) - p.row(cur)).squaredNorm());
            if (dmin[i] > best) {
                best = dmin[i];
                next = i;
            }
        }
        cur = next;
    }
    return out;
}

int keypoint_count(const std::string& kind) {
    if (kind == "bbx8" || kind == "fps8") return 8;
    if (kind == "fps4") return 4;
    if (kind == "fps12") return 12;
    G2L_CHECK(false, "keypoints: unknown keypoint kind '", kind,
              "' (expected bbx8, fps4, fps8 or fps12)");
    return 0;
}

Points keypoints(const Points& model_pts, const ModelInfo& info, const std::string& kind) {
    const int k = keypoint_count(kind);  // throws for an unknown kind
    return kind == "bbx8" ? bbox_corners(info) : farthest_point_sampling(model_pts, k);
}

Points keypoints(const Mesh& mesh, const ModelInfo& info, const std::string& kind) {
    return keypoints(mesh.vertices, info, kind);
}

}  // namespace g2l::geom
