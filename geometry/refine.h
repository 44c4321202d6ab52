// SPDX-License-Identifier: MIT
// Depth-based pose refinement: ICP of the object's observed depth points against its model
// surface, started from the network's pose and from that pose turned by the model box's
// axis-permuting rotations and axis turns (the near-symmetries a depth-only network confuses:
// a flat box's flips, a mug's handle side, a clamp's jaw side). The turn whose refined pose fits
// the depth best wins, when it fits clearly better than the network's own. Lengths in mm.
#pragma once

#include <cstdint>
#include <vector>

#include "geometry/labels.h"
#include "geometry/symmetry.h"
#include "geometry/types.h"

namespace g2l::geom {

struct RefineOptions {
    int iterations = 40;       ///< ICP iterations of the network's start and the finalists
    int coarse_iterations = 10; ///< ICP iterations of every start before they are ranked
    int finalists = 5;          ///< best turned starts that get the full iterations
    int max_points = 800;      ///< observed points used (evenly strided)
    /// Pairs farther apart than inlier_frac * diameter are left out of each Kabsch fit (outliers:
    /// background points the segmentation kept, the model's far side). Also the cap of the fit.
    double inlier_frac = 0.1;
    bool hypotheses = true;    ///< try the turned starts (false: ICP from the network's pose only)
    int axis_steps = 8;        ///< turns about each box axis at multiples of 360 / axis_steps deg
    /// A turned start replaces the network's pose only when its fit is below this fraction of
    /// the network's (refined) fit.
    double switch_ratio = 0.95;
    double free_space_frac = 0.05;  ///< see DepthImage
    int model_points = 500;         ///< model points projected for the free-space test
    double free_space_weight = 1.0; ///< cost = fit + weight * cap * violating fraction
    /// Support plane (needs the depth image): the dominant plane of the depth pixels around the
    /// object (its observed points' image box grown by plane_region box sizes on each side, so
    /// the object covers a small part of it), found by RANSAC, is taken as the surface the
    /// object stands on when it holds at least plane_min_inliers of those pixels; a pose whose
    /// posed model points lie more than plane_depth_mm beneath it (inside the table) pays for
    /// them like free-space violations (their fraction is added to the violating fraction).
    /// The plane's points are not removed from the observed points: a thin object's sides lie
    /// within millimetres of it (docs/experiments.md).
    bool support_plane = true;
    double plane_tol_mm = 4.0;      ///< RANSAC inlier distance
    double plane_depth_mm = 8.0;
    double plane_region = 1.0;
    double plane_min_inliers = 0.4;
    /// Clusters: when > 0 the observed points are also split into Euclidean clusters (points
    /// closer than cluster_frac * diameter joined) and, when there is more than one, each
    /// cluster holding at least cluster_min_share of them is searched on its own (the
    /// segmentation may have taken a neighbouring object along: the YCB-Video banana); the
    /// lowest cost wins. 0 = off.
    double cluster_frac = 0.1;
    double cluster_min_share = 0.25;
    /// With a ClosestPointGrid (refine_pose's `grid`): the finalists' ICP ends with this many
    /// steps on the exact k-d tree, and their fits are exact (the grid's nearest point is the
    /// nearest to its cell's centre, up to sqrt(3) cells off). Each exact step costs ~10 grid
    /// steps; 3 keep the accuracy 10 gave, at a third of the cost (docs/results.md, issue 37).
    int polish_iterations = 3;
    /// RefineResult::alt_fit_mm counts the finalists whose rotation lies more than this many
    /// degrees from the winner's, modulo the model's symmetries when refine_pose is given them
    /// (a box turned over onto itself is the same pose; a mug with its handle on the other side
    /// is not).
    double alt_min_deg = 30;
};

/// The model point nearest to the centre of each cell of a regular grid over the model points'
/// box grown by margin_mm on every side: a constant-time stand-in for ModelKdTree::nearest in
/// the refinement's many ICP steps (~85% of its time on the k-d tree otherwise). A point in a
/// cell gets that cell's model point, at most sqrt(3) * cell_mm farther than its true nearest
/// one; a point outside the grid lies farther than margin_mm from every model point. Built
/// once per model (OpenMP over cells, one k-d tree query per cell); int32 per cell. It also
/// sorts the model points into buckets for the exact queries of the refinement's polish
/// (nearest_below).
class ClosestPointGrid {
public:
    ClosestPointGrid() = default;
    /// Throws g2l::Error if cell_mm is not finite and > 0, margin_mm is not finite and >= 0, or
    /// the grid would exceed max_cells or 2^31 - 1 cells (naming its size).
    ClosestPointGrid(const ModelKdTree& tree, double cell_mm, double margin_mm,
                     int64_t max_cells = int64_t(1) << 24);
    /// For refine_pose with `opt` on the object `info`: cells of diameter / 80 (1 to 4 mm), the
    /// margin the ICP inlier cap needs (opt.inlier_frac * diameter).
    static ClosestPointGrid for_refine(const ModelKdTree& tree, const ModelInfo& info,
                                       const RefineOptions& opt = {});
    /// Row of the tree point nearest to the centre of x's cell; -1 outside the grid.
    int lookup(const Eigen::Vector3f& x) const {
        const float fx = (x.x() - lo_.x()) * inv_cell_, fy = (x.y() - lo_.y()) * inv_cell_,
                    fz = (x.z() - lo_.z()) * inv_cell_;
        if (!(fx >= 0.f && fy >= 0.f && fz >= 0.f)) return -1;  // also NaN
        if (!(fx < float(nx_) && fy < float(ny_) && fz < float(nz_))) return -1;
        return cells_[size_t(layout().offset(int(fx), int(fy), int(fz)))];
    }
    /// The exact nearest model point (of the tree the grid was built over) closer than
    /// bound_mm: its distance, its row to *index; infinity (and *index untouched) when none is.
    /// The same answer as ModelKdTree::nearest_below (bar the order among exactly equidistant
    /// points): it scans the model points of the buckets (cubes of bucket_mm()) the ball
    /// touches, so a tight bound (a point known to lie near) costs a few dozen distances
    /// instead of a descent of the k-d tree.
    float nearest_below(const Eigen::Vector3f& x, float bound_mm, int* index) const;
    /// The grid's raw layout, for loops that look up many points at once (see lookup): cell
    /// (ix, iy, iz), 0 <= ix < nx ..., is cells[offset(ix, iy, iz)] (x fastest).
    struct Layout {
        const int32_t* cells;
        float lo[3], inv_cell;
        int nx, ny, nz;
        int offset(int ix, int iy, int iz) const { return (iz * ny + iy) * nx + ix; }
    };
    Layout layout() const {
        return {cells_.data(), {lo_.x(), lo_.y(), lo_.z()}, inv_cell_, nx_, ny_, nz_};
    }
    double bucket_mm() const { return bucket_; }
    bool empty() const { return cells_.empty(); }
    double cell_mm() const { return cell_; }
    double margin_mm() const { return margin_; }
    int64_t size() const { return int64_t(nx_) * ny_ * nz_; }
    /// Points of the k-d tree it was built over (refine_pose checks it against its tree's).
    int64_t tree_points() const { return tree_points_; }

private:
    Eigen::Vector3f lo_ = Eigen::Vector3f::Zero();
    float inv_cell_ = 0;
    double cell_ = 0, margin_ = 0;
    int nx_ = 0, ny_ = 0, nz_ = 0;
    int64_t tree_points_ = 0;
    std::vector<int32_t> cells_;  // x fastest (Layout::offset)
    // The model points sorted into buckets (x fastest): bucket b's points are rows
    // [bucket_start_[b], bucket_start_[b + 1]) of bucket_pts_ (every point's x, then every y,
    // then every z: a row of buckets loads contiguously), their tree rows in bucket_row_.
    Eigen::Vector3f bucket_lo_ = Eigen::Vector3f::Zero();
    float inv_bucket_ = 0;
    double bucket_ = 0;
    int64_t bnx_ = 0, bny_ = 0, bnz_ = 0;
    std::vector<int32_t> bucket_start_, bucket_row_;
    std::vector<float> bucket_pts_;
};

/// A plane n . p + d = 0 in the camera frame (unit n, the camera on its positive side, d > 0).
struct Plane {
    Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
    double d = 0;
    double inlier_frac = 0;  ///< share of the sampled pixels within the RANSAC tolerance
};

/// The frame's depth image (row-major, mm; 0 / NaN = no measurement) for the free-space test:
/// a posed model point that the camera would see in front of the measured surface (depth
/// farther than the point by more than free_space_frac * diameter) is a violation.
struct DepthImage {
    const float* depth_mm = nullptr;
    Intrinsics K;  ///< with width and height
};

struct RefineResult {
    Pose pose;
    /// the cost the search ranks by (pose_cost): the mean observed-point distance to the posed
    /// model, capped (see above), plus the free-space and support-plane penalties
    double fit_mm = 0;
    double start_fit_mm = 0;  ///< the same for the refined network pose (hypothesis 0)
    /// fraction of projected model points violating free space, plus the fraction beneath the
    /// support plane when one was found
    double violation = 0;
    int hypothesis = 0;     ///< 0 = the network's pose, else the index of the turn that won
    int hypotheses = 1;     ///< starts tried
    bool plane = false;     ///< a support plane was found and used
    int cluster = -1;       ///< -1: all observed points; else the cluster (largest first) that won
    int observed = 0;       ///< observed points the winning search used
    /// The lowest cost (as fit_mm) among the winning search's finalists that are a distinct pose
    /// (RefineOptions::alt_min_deg): a pose the depth also allows (a mug's handle
    /// on the other side, a clamp's jaws the other way). Near fit_mm (it may be a little below:
    /// switch_ratio), the depth cannot tell the two apart; -1 when no finalist is distinct (or
    /// hypotheses are off).
    double alt_fit_mm = -1;
};

/// The dominant plane of the measured pixels of `depth` in the image box [x0, x1) x [y0, y1)
/// (clipped to the image): at most max_samples pixels on an even grid are back-projected and
/// `iterations` deterministic RANSAC draws keep the plane with the most points within tol_mm,
/// refitted to them by least squares. Returns false when fewer than 3 pixels are measured or no
/// draw spans a plane. Deterministic.
bool fit_plane(const DepthImage& depth, int x0, int y0, int x1, int y1, double tol_mm, Plane* out,
               int max_samples = 3000, int iterations = 200);

/// Connected components of `pts` under "closer than radius" (what refine_pose's clusters are):
/// the components largest first, rows ascending in each, components of one size in the order
/// of their first row. Throws g2l::Error if radius is not finite and > 0 or a point is not
/// finite.
std::vector<std::vector<int64_t>> euclidean_clusters(const Points& pts, double radius);

/// Mean over `obs` (camera frame) of min(distance to the model posed at `pose`, cap_mm).
double fit_error(const ModelKdTree& tree, const Points& obs, const Pose& pose, double cap_mm);

/// Point-to-point ICP of `obs` (camera-frame object points) onto the model surface `tree`
/// (model frame), from `init` — point-to-plane when `normals` (tree.normals(), one row per tree
/// point) are given, which converges in far fewer steps along flat faces — each start ranked by its fit plus, when `depth` is given, its
/// free-space violations. With `grid` (ClosestPointGrid::for_refine of the same tree, cached
/// per model by the caller) the starts' ICP and ranking look nearest points up in the grid and
/// the finalists end with opt.polish_iterations exact steps (the grid's buckets searched within
/// the distance of the grid's point or of the point's previous nearest one): ~8x faster, the
/// same poses within a fraction of a millimetre
/// (docs/results.md). Throws g2l::Error if obs has fewer than 3 rows, a point or the init pose
/// is not finite, info.diameter is not > 0, or the grid was built over another tree or with a
/// margin below the inlier cap (opt.inlier_frac * diameter). `syms` (geometric_symmetries of
/// the model, optional) only decide which finalists are distinct poses (alt_fit_mm).
RefineResult refine_pose(const ModelKdTree& tree, const ModelInfo& info, const Points& obs,
                         const Pose& init, const RefineOptions& opt = {},
                         const DepthImage* depth = nullptr, const Points* normals = nullptr,
                         const ClosestPointGrid* grid = nullptr,
                         const std::vector<SymmetryTransform>* syms = nullptr);

/// The cost refine_pose ranks its poses by, of `pose` as it is (no ICP step): the capped mean
/// distance of the observed points (at most opt.max_points, strided) to the posed model, plus
/// opt.free_space_weight * cap times the free-space and support-plane violations (the plane
/// found around `obs` as refine_pose finds it). What RefineResult::fit_mm holds for the pose
/// refine_pose returns; g2l_eval writes it for the ground-truth pose (gt_fit_mm) to tell a
/// search that missed a better-fitting pose from a cost that prefers a wrong one. Throws like
/// refine_pose.
double pose_cost(const ModelKdTree& tree, const ModelInfo& info, const Points& obs,
                 const Pose& pose, const RefineOptions& opt = {}, const DepthImage* depth = nullptr);

/// Fraction of `model_pts` (model frame) posed at `pose` that project onto a measured pixel of
/// `depth` and lie in front of the measured surface by more than tol_mm, among those that
/// project onto a measured pixel and are not behind it by more than tol_mm (0 when none).
double free_space_violation(const Points& model_pts, const Pose& pose, const DepthImage& depth,
                            double tol_mm);

}  // namespace g2l::geom
