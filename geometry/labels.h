// SPDX-License-Identifier: MIT
// Per-point object/background labels from a posed model (G2L-Net §4.2: a scene point is object
// when it lies within 8 mm of the GT-posed model). Lengths in millimetres.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "geometry/types.h"

namespace g2l::geom {

/// Points on the triangles of `mesh` (mm, model frame), for a surface that is denser than the
/// vertices. Each triangle gets a regular barycentric grid with m = ceil(longest edge / spacing)
/// divisions per edge, so the sample count grows with the triangle's area and every surface point
/// lies within about `spacing_mm` of a sample or vertex. The triangle corners (= vertices) are
/// not repeated. Deterministic (no random numbers); OpenMP over triangles, output in face order.
/// Throws g2l::Error if spacing_mm is not finite and > 0, a face index is out of range, or the
/// result would exceed 50 million points.
Points sample_surface(const Mesh& mesh, double spacing_mm = 2.0);

/// A KD-tree over a fixed point set (nanoflann), built once per object and queried many times.
/// The tree keeps its own copy of the points. Queries are const and thread-safe.
class ModelKdTree {
public:
    /// Builds the tree over `pts` (N x 3, mm). Throws g2l::Error if N == 0 or a point is not
    /// finite (naming the row).
    explicit ModelKdTree(const Points& pts);

    /// Tree over the mesh vertices plus sample_surface(mesh, spacing_mm).
    static ModelKdTree from_mesh(const Mesh& mesh, double spacing_mm = 2.0);

    ~ModelKdTree();
    ModelKdTree(ModelKdTree&&) noexcept;
    ModelKdTree& operator=(ModelKdTree&&) noexcept;
    ModelKdTree(const ModelKdTree&) = delete;
    ModelKdTree& operator=(const ModelKdTree&) = delete;

    /// Euclidean distance (mm) from q to the nearest tree point; its row index goes to *index if
    /// non-null. Ties between equidistant points are resolved by the tree, not by index.
    float nearest(const Eigen::Vector3f& q, int* index = nullptr) const;

    /// The same nearest point when it lies closer than `bound_mm`: the search prunes every branch
    /// beyond the bound, so a caller that knows a near point (a ClosestPointGrid's, whose
    /// distance bounds the nearest one's) gets the exact answer for a fraction of the search.
    /// Returns infinity (and leaves *index alone) when no tree point is closer than bound_mm.
    float nearest_below(const Eigen::Vector3f& q, float bound_mm, int* index) const;

    /// The k nearest tree points of q (k >= 1, at most size()), nearest first: row indices to
    /// idx[0..k), squared distances to d2[0..k). Returns the number found.
    int knn(const Eigen::Vector3f& q, int k, int* idx, float* d2) const;

    /// Unit surface normals at the tree points (N x 3, sign arbitrary): the direction of least
    /// spread of each point's k nearest neighbours (PCA). OpenMP over points. Throws g2l::Error
    /// if k < 3.
    Points normals(int k = 10) const;

    /// Labels camera-frame points: 1 if the distance from R^T (p - t) (the point in the model
    /// frame) to the nearest tree point is < threshold_mm, else 0 (also 0 for a non-finite
    /// point). OpenMP over points.
    /// Returns N values. Throws g2l::Error if threshold_mm is not finite and > 0.
    std::vector<uint8_t> label_points(const Points& cam_pts, const Pose& pose,
                                      float threshold_mm = 8.f) const;

    /// Number of points in the tree.
    int64_t size() const;

    /// The points the tree was built over (N x 3).
    const Points& points() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace g2l::geom
