// SPDX-License-Identifier: MIT
#include "geometry/labels.h"

#include <Eigen/Eigenvalues>
#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace g2l::geom {

/// nanoflann's dataset adaptor over the row-major N x 3 point matrix.
struct PointsAdaptor {
    const Points* pts = nullptr;
    size_t kdtree_get_point_count() const { return static_cast<size_t>(pts->rows()); }
    float kdtree_get_pt(size_t i, size_t d) const {
        return (*pts)(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(d));
    }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const { return false; }
};

using KdIndex = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, PointsAdaptor>, PointsAdaptor, 3, uint32_t>;

struct ModelKdTree::Impl {
    Points pts;
    PointsAdaptor adaptor;
    std::unique_ptr<KdIndex> index;
};

Points sample_surface(const Mesh& mesh, double spacing_mm) {
    G2L_CHECK(std::isfinite(spacing_mm) && spacing_mm > 0, "sample_surface: spacing_mm must be "
              "finite and > 0, got ", spacing_mm);
    const Eigen::Index nf = mesh.faces.rows(), nv = mesh.vertices.rows();
    // Pass 1: grid divisions per triangle and output offsets (serial prefix sum -> fixed order).
    std::vector<int> div(static_cast<size_t>(nf));
    std::vector<int64_t> offset(static_cast<size_t>(nf) + 1, 0);
    for (Eigen::Index f = 0; f < nf; ++f) {
        Eigen::Vector3d v[3];
        for (int c = 0; c < 3; ++c) {
            const int32_t id = mesh.faces(f, c);
            G2L_CHECK(id >= 0 && id < nv, "sample_surface: face ", f, " index ", id,
                      " out of range (", nv, " vertices) in '", mesh.path, "'");
            v[c] = mesh.vertices.row(id).cast<double>();
        }
        const double edge = std::max({(v[1] - v[0]).norm(), (v[2] - v[1]).norm(),
                                      (v[0] - v[2]).norm()});
        const double m = std::ceil(edge / spacing_mm);
        G2L_CHECK(m < 1e5, "sample_surface: face ", f, " needs ", m, " divisions at spacing ",
                  spacing_mm, " mm (edge ", edge, " mm)");
        div[f] = std::max(1, static_cast<int>(m));
        // Grid points (i, j) with i + j <= m: (m+1)(m+2)/2, minus the 3 corners.
        const int64_t mm = div[f];
        offset[f + 1] = offset[f] + (mm + 1) * (mm + 2) / 2 - 3;
        G2L_CHECK(offset[f + 1] <= 50'000'000, "sample_surface: more than 50 million samples at "
                  "spacing ", spacing_mm, " mm; use a larger spacing");
    }
    Points out(offset[nf], 3);
    // Pass 2: fill each triangle's slice independently.
#pragma omp parallel for schedule(dynamic, 256)
    for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::RowVector3f a = mesh.vertices.row(mesh.faces(f, 0));
        const Eigen::RowVector3f b = mesh.vertices.row(mesh.faces(f, 1));
        const Eigen::RowVector3f c = mesh.vertices.row(mesh.faces(f, 2));
        const int m = div[f];
        int64_t o = offset[f];
        for (int i = 0; i <= m; ++i) {
            for (int j = 0; i + j <= m; ++j) {
                const int k = m - i - j;
                if (i == m || j == m || k == m) continue;  // a corner: already a vertex
                const float wa = float(i) / m, wb = float(j) / m, wc = float(k) / m;
                out.row(o++) = wa * a + wb * b + wc * c;
            }
        }
    }
    return out;
}

ModelKdTree::ModelKdTree(const Points& pts) : impl_(std::make_unique<Impl>()) {
    G2L_CHECK(pts.rows() > 0, "ModelKdTree: empty point set");
    G2L_CHECK(pts.rows() < (int64_t(1) << 31), "ModelKdTree: too many points (", pts.rows(), ")");
    for (Eigen::Index i = 0; i < pts.rows(); ++i) {
        G2L_CHECK(pts.row(i).allFinite(), "ModelKdTree: point ", i, " is not finite (",
                  pts.row(i), ")");
    }
    impl_->pts = pts;
    impl_->adaptor.pts = &impl_->pts;
    impl_->index = std::make_unique<KdIndex>(3, impl_->adaptor,
                                             nanoflann::KDTreeSingleIndexAdaptorParams(16));
}

ModelKdTree ModelKdTree::from_mesh(const Mesh& mesh, double spacing_mm) {
    const Points samples = sample_surface(mesh, spacing_mm);
    Points all(mesh.vertices.rows() + samples.rows(), 3);
    all << mesh.vertices, samples;
    return ModelKdTree(all);
}

ModelKdTree::~ModelKdTree() = default;
ModelKdTree::ModelKdTree(ModelKdTree&&) noexcept = default;
ModelKdTree& ModelKdTree::operator=(ModelKdTree&&) noexcept = default;

float ModelKdTree::nearest(const Eigen::Vector3f& q, int* index) const {
    uint32_t idx = 0;
    float d2 = 0;
    impl_->index->knnSearch(q.data(), 1, &idx, &d2);
    if (index) *index = static_cast<int>(idx);
    return std::sqrt(d2);
}

float ModelKdTree::nearest_below(const Eigen::Vector3f& q, float bound_mm, int* index) const {
    uint32_t idx = 0;
    float d2 = 0;
    nanoflann::KNNResultSet<float, uint32_t> rs(1);
    rs.init(&idx, &d2);
    d2 = bound_mm * bound_mm;  // the result set's worst distance: the search's pruning radius
    impl_->index->findNeighbors(rs, q.data(), nanoflann::SearchParams());
    if (rs.size() == 0) return std::numeric_limits<float>::infinity();
    *index = static_cast<int>(idx);
    return std::sqrt(d2);
}

int ModelKdTree::knn(const Eigen::Vector3f& q, int k, int* idx, float* d2) const {
    G2L_CHECK(k >= 1, "ModelKdTree::knn: k must be >= 1, got ", k);
    std::vector<uint32_t> ix(static_cast<size_t>(k));
    const size_t found = impl_->index->knnSearch(q.data(), size_t(k), ix.data(), d2);
    for (size_t i = 0; i < found; ++i) idx[i] = static_cast<int>(ix[i]);
    return static_cast<int>(found);
}

Points ModelKdTree::normals(int k) const {
    G2L_CHECK(k >= 3, "ModelKdTree::normals: k must be >= 3, got ", k);
    const Points& pts = points();
    const int64_t n = pts.rows();
    Points out(n, 3);
#pragma omp parallel for schedule(dynamic, 1024)
    for (int64_t i = 0; i < n; ++i) {
        std::vector<int> idx(static_cast<size_t>(k));
        std::vector<float> d2(static_cast<size_t>(k));
        const int m = knn(pts.row(i).transpose(), k, idx.data(), d2.data());
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (int j = 0; j < m; ++j) mean += pts.row(idx[size_t(j)]).cast<double>().transpose();
        mean /= std::max(1, m);
        Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
        for (int j = 0; j < m; ++j) {
            const Eigen::Vector3d d = pts.row(idx[size_t(j)]).cast<double>().transpose() - mean;
            C += d * d.transpose();
        }
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
        out.row(i) = es.eigenvectors().col(0).cast<float>().transpose();
    }
    return out;
}

std::vector<uint8_t> ModelKdTree::label_points(const Points& cam_pts, const Pose& pose,
                                               float threshold_mm) const {
    G2L_CHECK(std::isfinite(threshold_mm) && threshold_mm > 0, "label_points: threshold_mm must "
              "be finite and > 0, got ", threshold_mm);
    G2L_CHECK(pose.R.allFinite() && pose.t.allFinite(), "label_points: pose is not finite");
    const int64_t n = cam_pts.rows();
    std::vector<uint8_t> lab(static_cast<size_t>(n), 0);
    // Model frame: x_model = R^T (x_cam - t).
    const Eigen::Matrix3d Rt = pose.R.transpose();
#pragma omp parallel for schedule(dynamic, 1024)
    for (int64_t i = 0; i < n; ++i) {
        const Eigen::Vector3d pc = cam_pts.row(i).cast<double>().transpose();
        if (!pc.allFinite()) continue;  // no measurement -> background
        const Eigen::Vector3f pm = (Rt * (pc - pose.t)).cast<float>();
        lab[i] = nearest(pm) < threshold_mm ? 1 : 0;
    }
    return lab;
}

int64_t ModelKdTree::size() const { return impl_->pts.rows(); }

const Points& ModelKdTree::points() const { return impl_->pts; }

}  // namespace g2l::geom
