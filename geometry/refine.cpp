// SPDX-License-Identifier: MIT
#include "geometry/refine.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <limits>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif
#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "core/error.h"
#include "core/job_pool.h"
#include "geometry/kabsch.h"
#include "geometry/metrics.h"

namespace g2l::geom {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Runs body(i) for every i in [0, n), each independent of the others (the results depend
// neither on the thread count nor on the order): as jobs of the calling thread's JobPool when
// it has one (a frame's objects refined together, each a job, so one object's serial parts and
// its last starts overlap another's work, and a thread waiting for its pieces runs other
// objects' pieces meanwhile; see infer::FramePipeline::estimate), as OpenMP tasks inside
// another parallel region, else as a parallel loop. body's exceptions are rethrown after all
// the pieces ran, the lowest index's first.
template <class Body>
void for_each_index(int64_t n, const Body& body) {
    PieceErrors errors(size_t(std::max<int64_t>(0, n)));
    auto piece = [&](int64_t i) { errors.run(size_t(i), [&] { body(i); }); };
    if (JobPool* pool = current_job_pool()) {
        JobPool::Group group;
        for (int64_t i = 0; i < n; ++i) pool->submit(group, [&piece, i] { piece(i); });
        pool->close(group);
        pool->wait(group);
    } else {
#ifdef _OPENMP
        if (omp_in_parallel()) {
#pragma omp taskloop grainsize(1) shared(piece)
            for (int64_t i = 0; i < n; ++i) piece(i);
        } else {
#pragma omp parallel for schedule(dynamic, 1)
            for (int64_t i = 0; i < n; ++i) piece(i);
        }
#else
        for (int64_t i = 0; i < n; ++i) piece(i);
#endif
    }
    errors.rethrow_first();
}

// The turns tried besides the identity: the 23 other proper axis permutations of the model box
// and the turns about each box axis at multiples of 360 / steps degrees (duplicates removed).
std::vector<Eigen::Matrix3d> turns(int steps) {
    std::vector<Eigen::Matrix3d> out{Eigen::Matrix3d::Identity()};
    auto add = [&](const Eigen::Matrix3d& R) {
        for (const auto& o : out)
            if ((o - R).cwiseAbs().maxCoeff() < 1e-6) return;
        out.push_back(R);
    };
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (const auto& p : perms)
        for (int s = 0; s < 8; ++s) {
            Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
            for (int r = 0; r < 3; ++r) R(r, p[r]) = (s >> r) & 1 ? -1.0 : 1.0;
            if (R.determinant() > 0) add(R);
        }
    for (int a = 0; a < 3; ++a)
        for (int j = 1; j < steps; ++j)
            add(Eigen::AngleAxisd(2 * kPi * j / steps, Eigen::Vector3d::Unit(a)).toRotationMatrix());
    return out;
}

// Distance from x (model frame) to its nearest model point, that point's row to *index: with
// `grid` and not `exact`, the point of x's cell (infinity outside the grid); else the k-d tree's
// exact one, its search bounded by the cell's point when there is one (the nearest point is no
// farther than it; the same answer as the unbounded search, in a fraction of its time).
inline float nearest_of(const ModelKdTree& tree, const ClosestPointGrid* grid, bool exact,
                        const Eigen::Vector3f& x, int* index) {
    if (!grid) return tree.nearest(x, index);
    const int k = grid->lookup(x);
    if (k < 0 && exact) return tree.nearest(x, index);
    if (k < 0) {
        *index = 0;
        return std::numeric_limits<float>::infinity();
    }
    *index = k;
    const float d0 = (x - tree.points().row(k).transpose()).norm();
    if (!exact) return d0;
    const float d = tree.nearest_below(x, d0 * (1.f + 1e-5f) + 1e-6f, index);
    return std::isfinite(d) ? d : d0;
}

// fit_error, with the grid's nearest points when `grid` is set and not `exact`.
double fit_with(const ModelKdTree& tree, const ClosestPointGrid* grid, bool exact,
                const Points& obs, const Pose& pose, double cap_mm) {
    if (obs.rows() == 0) return cap_mm;
    const Eigen::Matrix3f Rt = pose.R.transpose().cast<float>();
    const Eigen::Vector3f t = pose.t.cast<float>();
    double sum = 0;
    int idx = 0;
    for (int64_t i = 0; i < obs.rows(); ++i) {
        const Eigen::Vector3f q = obs.row(i).transpose();
        sum += std::min<double>(cap_mm, nearest_of(tree, grid, exact, Rt * (q - t), &idx));
    }
    return sum / double(obs.rows());
}

struct Icp {
    using Mat6 = Eigen::Matrix<double, 6, 6>;
    using Vec6 = Eigen::Matrix<double, 6, 1>;
    const ModelKdTree& tree;
    const Points& obs;
    const Points* normals;  // point-to-plane when set
    double cap_mm;
    Points M, Q;   // scratch pairs (point-to-point only)
    std::vector<float> d;
    std::vector<int> idx;
    std::vector<int> hint;  // exact passes: each observed point's nearest model point last pass

    // `iters` ICP steps from `pose` (nearest points from `grid` when set and not `exact`, else
    // the k-d tree's); returns the fit of the final pose, measured the same way (NaN, and one
    // pass over the points saved, when !want_fit: a caller that goes on from the pose).
    double run(Pose& pose, int iters, const ClosestPointGrid* grid, bool exact, bool want_fit = true) {
        return normals ? run_plane(pose, iters, grid, exact, want_fit)
                       : run_point(pose, iters, grid, exact, want_fit);
    }

    // The fit (as fit_with) of the last plane_pass's distances, summed in their order.
    double fit_of_pass() const {
        const int64_t n = obs.rows();
        if (n == 0) return cap_mm;
        double sum = 0;
        for (int64_t i = 0; i < n; ++i) sum += std::min<double>(cap_mm, d[size_t(i)]);
        return sum / double(n);
    }

    // One pass over the observed points at `pose`: the fit (as fit_with) when `A` is null, else
    // NaN (fit_of_pass() gives it: the steps seldom need it, and its in-order sum is a chain of
    // additions) and point-to-plane's normal equations over the inliers (pairs within cap_mm; a tighter,
    // median-based cut keeps only the points that already lie on the surface, and a pose slid
    // along a flat face stays there), their count to *m. In the model frame x = R^T (q - t)
    // moves to dR x + dt with dR = I + [w]x; minimise sum ((x - m_i).n_i + w.(x x n_i) + dt.n_i)^2.
    double plane_pass(const Pose& pose, const ClosestPointGrid* grid, bool exact, Mat6* A, Vec6* b,
                      int64_t* m) {
        const int64_t n = obs.rows();
        if (n == 0) return cap_mm;
        const Eigen::Matrix3f Rt = pose.R.transpose().cast<float>();
        const Eigen::Vector3f t = pose.t.cast<float>();
        // 1. Each point's nearest model point and its distance.
        d.resize(size_t(n));
        idx.resize(size_t(n));
        if (grid && !exact) {
            // The grid's points for a vector of observed points at a time (gathers of the cells
            // and of their model points; one point at a time took ~25% more of the refinement's
            // time): squared distances first, their roots after.
            const ClosestPointGrid::Layout g = grid->layout();
            const float q00 = Rt(0, 0), q01 = Rt(0, 1), q02 = Rt(0, 2), q10 = Rt(1, 0), q11 = Rt(1, 1),
                        q12 = Rt(1, 2), q20 = Rt(2, 0), q21 = Rt(2, 1), q22 = Rt(2, 2);
            const float s0 = t.x(), s1 = t.y(), s2 = t.z();
            const float* O = obs.data();
            const float* MP = tree.points().data();
            float* D = d.data();
            int* I = idx.data();
            const float fnx = float(g.nx), fny = float(g.ny), fnz = float(g.nz);
#pragma omp simd
            for (int64_t i = 0; i < n; ++i) {
                const float a0 = O[3 * i] - s0, a1 = O[3 * i + 1] - s1, a2 = O[3 * i + 2] - s2;
                const float x0 = q00 * a0 + q01 * a1 + q02 * a2;
                const float x1 = q10 * a0 + q11 * a1 + q12 * a2;
                const float x2 = q20 * a0 + q21 * a1 + q22 * a2;
                const float fx = (x0 - g.lo[0]) * g.inv_cell, fy = (x1 - g.lo[1]) * g.inv_cell,
                            fz = (x2 - g.lo[2]) * g.inv_cell;
                const bool in = (fx >= 0.f) & (fy >= 0.f) & (fz >= 0.f) & (fx < fnx) & (fy < fny) & (fz < fnz);
                const int c = in ? g.offset(int(fx), int(fy), int(fz)) : 0;
                const int k = g.cells[c] & (in ? -1 : 0);
                const float m0 = x0 - MP[3 * k], m1 = x1 - MP[3 * k + 1], m2 = x2 - MP[3 * k + 2];
                D[i] = in ? m0 * m0 + m1 * m1 + m2 * m2 : std::numeric_limits<float>::infinity();
                I[i] = k;
            }
            for (int64_t i = 0; i < n; ++i) D[i] = std::sqrt(D[i]);
        } else {
            for (int64_t i = 0; i < n; ++i) {
                const Eigen::Vector3f xf = Rt * (obs.row(i).transpose() - t);
                int j = 0;
                const float di = grid ? nearest_hinted(*grid, xf, &hint[size_t(i)], &j)
                                      : nearest_of(tree, nullptr, true, xf, &j);
                d[size_t(i)] = di;
                idx[size_t(i)] = j;
            }
        }
        if (!A) return fit_of_pass();
        // 2. The normal equations, vectorised across the points (each lane its own partial sums;
        //    the rounding differs from a one-by-one sum in the last bits): every point's terms,
        //    an outlier's weighted by 0 (~1/3 of the refinement's time before, point by point).
        const float *O = obs.data(), *MP = tree.points().data(), *NP = normals->data();
        const float* D = d.data();
        const int* I = idx.data();
        const Eigen::Matrix3d R = pose.R.transpose();
        const double r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2), r10 = R(1, 0), r11 = R(1, 1),
                     r12 = R(1, 2), r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
        const double t0 = pose.t.x(), t1 = pose.t.y(), t2 = pose.t.z(), cap = cap_mm;
        // The upper triangle of A (aRC) and b.
        double a00 = 0, a01 = 0, a02 = 0, a03 = 0, a04 = 0, a05 = 0, a11 = 0, a12 = 0, a13 = 0,
               a14 = 0, a15 = 0, a22 = 0, a23 = 0, a24 = 0, a25 = 0, a33 = 0, a34 = 0, a35 = 0,
               a44 = 0, a45 = 0, a55 = 0, b0 = 0, b1 = 0, b2 = 0, b3 = 0, b4 = 0, b5 = 0, in = 0;
#pragma omp simd reduction(+ : a00, a01, a02, a03, a04, a05, a11, a12, a13, a14, a15, a22, a23, \
                               a24, a25, a33, a34, a35, a44, a45, a55, b0, b1, b2, b3, b4, b5, in)
        for (int64_t i = 0; i < n; ++i) {
            const double w = double(D[i]) <= cap ? 1.0 : 0.0;
            const int64_t j = I[i];
            const double q0 = double(O[3 * i]) - t0, q1 = double(O[3 * i + 1]) - t1,
                         q2 = double(O[3 * i + 2]) - t2;
            const double x0 = r00 * q0 + r01 * q1 + r02 * q2, x1 = r10 * q0 + r11 * q1 + r12 * q2,
                         x2 = r20 * q0 + r21 * q1 + r22 * q2;  // the model frame
            const double n0 = NP[3 * j], n1 = NP[3 * j + 1], n2 = NP[3 * j + 2];
            const double m0 = MP[3 * j], m1 = MP[3 * j + 1], m2 = MP[3 * j + 2];
            // J = (x x n, n), the residual (x - m) . n.
            const double c0 = x1 * n2 - x2 * n1, c1 = x2 * n0 - x0 * n2, c2 = x0 * n1 - x1 * n0;
            const double r = (x0 - m0) * n0 + (x1 - m1) * n1 + (x2 - m2) * n2;
            const double w0 = w * c0, w1 = w * c1, w2 = w * c2, w3 = w * n0, w4 = w * n1,
                         w5 = w * n2;
            a00 += w0 * c0, a01 += w0 * c1, a02 += w0 * c2, a03 += w0 * n0, a04 += w0 * n1,
                a05 += w0 * n2;
            a11 += w1 * c1, a12 += w1 * c2, a13 += w1 * n0, a14 += w1 * n1, a15 += w1 * n2;
            a22 += w2 * c2, a23 += w2 * n0, a24 += w2 * n1, a25 += w2 * n2;
            a33 += w3 * n0, a34 += w3 * n1, a35 += w3 * n2;
            a44 += w4 * n1, a45 += w4 * n2;
            a55 += w5 * n2;
            b0 -= w0 * r, b1 -= w1 * r, b2 -= w2 * r, b3 -= w3 * r, b4 -= w4 * r, b5 -= w5 * r;
            in += w;
        }
        const double u[21] = {a00, a01, a02, a03, a04, a05, a11, a12, a13, a14, a15,
                              a22, a23, a24, a25, a33, a34, a35, a44, a45, a55};
        for (int row = 0, e = 0; row < 6; ++row)
            for (int col = row; col < 6; ++col, ++e) (*A)(row, col) = (*A)(col, row) = u[e];
        *b << b0, b1, b2, b3, b4, b5;
        *m = int64_t(in);
        return std::numeric_limits<double>::quiet_NaN();
    }

    // The exact nearest model point of x (model frame), as nearest_of's exact road, found in
    // the grid's buckets within the distance of *hint (the point this observed point had in
    // the previous pass: the pose moved little, so it mostly is the nearest one again, and the
    // ball the buckets must cover shrinks to the true distance; the grid cell's point, a random
    // read of the grid, is not needed then), or on the first pass of the grid cell's point. A
    // point with no model point within the inlier cap gets a distance beyond the cap (its
    // exact value matters to no one: the fit caps it and the step leaves it out), so no search
    // reaches farther than the cap. *hint becomes the answer.
    float nearest_hinted(const ClosestPointGrid& grid, const Eigen::Vector3f& x, int* hint,
                         int* index) const {
        const Points& mp = tree.points();
        float bound = std::numeric_limits<float>::infinity();
        int cand = -1;
        if (*hint >= 0) {  // the pose moved little: mostly the nearest point again
            bound = (x - mp.row(*hint).transpose()).norm();
            cand = *hint;
        } else if (const int k = grid.lookup(x); k >= 0) {
            bound = (x - mp.row(k).transpose()).norm();
            cand = k;
        }
        const float beyond_cap = float(cap_mm) * (1.f + 1e-5f) + 1e-3f;
        const float b = std::min(bound, beyond_cap);
        float d = grid.nearest_below(x, b * (1.f + 1e-5f) + 1e-6f, index);
        if (!std::isfinite(d)) {  // nothing within b: no model point within the cap
            *index = cand >= 0 ? cand : 0;
            d = cand >= 0 ? bound : std::numeric_limits<float>::infinity();
        }
        *hint = *index;
        return d;
    }

    double run_plane(Pose& pose, int iters, const ClosestPointGrid* grid, bool exact, bool want_fit) {
        if (grid && exact) hint.assign(size_t(obs.rows()), -1);
        Mat6 A;
        Vec6 b;
        int64_t m = 0;
        for (int it = 0;; ++it) {
            const bool last = it >= iters;
            if (last && !want_fit) return std::numeric_limits<double>::quiet_NaN();
            if (last) return plane_pass(pose, grid, exact, nullptr, nullptr, nullptr);
            plane_pass(pose, grid, exact, &A, &b, &m);
            if (m < 3) return fit_of_pass();
            A.diagonal().array() += 1e-6 * double(m);  // damping: flat or round surfaces
            const Vec6 sol = A.ldlt().solve(b);
            if (!sol.allFinite()) return fit_of_pass();
            const Eigen::Vector3d w = sol.head<3>(), dtm = sol.tail<3>();
            const double ang = w.norm();
            const Eigen::Matrix3d dR = ang > 1e-12 ? Eigen::AngleAxisd(ang, w / ang).toRotationMatrix()
                                                   : Eigen::Matrix3d::Identity();
            // New inverse pose dR R^T (q - t) + dt = R'^T (q - t') with R' = R dR^T,
            // t' = t - R' dt.
            Pose next;
            next.R = pose.R * dR.transpose();
            next.t = pose.t - next.R * dtm;
            const bool settled = (next.R - pose.R).cwiseAbs().maxCoeff() < 1e-5 &&
                                 (next.t - pose.t).norm() < 1e-3;
            pose = next;
            if (settled)
                return want_fit ? plane_pass(pose, grid, exact, nullptr, nullptr, nullptr)
                                : std::numeric_limits<double>::quiet_NaN();
        }
    }

    // Point-to-point: Kabsch over the inlier pairs.
    double run_point(Pose& pose, int iters, const ClosestPointGrid* grid, bool exact, bool want_fit) {
        const int64_t n = obs.rows();
        M.resize(n, 3);
        Q.resize(n, 3);
        d.resize(size_t(n));
        idx.resize(size_t(n));
        const Points& mp = tree.points();
        for (int it = 0; it < iters; ++it) {
            const Eigen::Matrix3f Rt = pose.R.transpose().cast<float>();
            const Eigen::Vector3f t = pose.t.cast<float>();
            for (int64_t i = 0; i < n; ++i) {
                const Eigen::Vector3f q = obs.row(i).transpose();
                d[size_t(i)] = nearest_of(tree, grid, exact, Rt * (q - t), &idx[size_t(i)]);
            }
            int64_t m = 0;
            for (int64_t i = 0; i < n; ++i) {
                if (d[size_t(i)] > cap_mm) continue;
                M.row(m) = mp.row(idx[size_t(i)]);
                Q.row(m) = obs.row(i);
                ++m;
            }
            if (m < 3) break;
            const Pose next = kabsch_pose(Points(M.topRows(m)), Points(Q.topRows(m)));
            const double dR = (next.R - pose.R).cwiseAbs().maxCoeff();
            const double dt = (next.t - pose.t).norm();
            pose = next;
            if (dR < 1e-5 && dt < 1e-3) break;
        }
        return want_fit ? fit_with(tree, grid, exact, obs, pose, cap_mm)
                        : std::numeric_limits<double>::quiet_NaN();
    }
};

}  // namespace

// The points are sorted into cubes of at least the radius (at most 64 along an axis): a point's
// neighbours lie in its own cube and the 26 around it.
std::vector<std::vector<int64_t>> euclidean_clusters(const Points& pts, double radius) {
    G2L_CHECK(std::isfinite(radius) && radius > 0, "euclidean_clusters: radius must be > 0, got ",
              radius);
    for (int64_t i = 0; i < pts.rows(); ++i)
        G2L_CHECK(pts.row(i).allFinite(), "euclidean_clusters: point ", i, " is not finite");
    const int64_t n = pts.rows();
    std::vector<std::vector<int64_t>> out;
    if (n == 0) return out;
    const float r2 = float(radius * radius);
    const Eigen::Vector3f lo = pts.colwise().minCoeff().transpose();
    const Eigen::Vector3f ext = pts.colwise().maxCoeff().transpose() - lo;
    const double cube = std::max(radius, double(ext.maxCoeff()) / 64.0);
    int64_t dim[3];
    for (int a = 0; a < 3; ++a) dim[a] = int64_t(double(ext[a]) / cube) + 1;
    auto coord = [&](int64_t i, int a) {
        return std::min<int64_t>(dim[a] - 1, int64_t(double(pts(i, a) - lo[a]) / cube));
    };
    std::vector<int64_t> cell_of(static_cast<size_t>(n)), start(size_t(dim[0] * dim[1] * dim[2] + 1), 0);
    for (int64_t i = 0; i < n; ++i) {
        cell_of[size_t(i)] = (coord(i, 2) * dim[1] + coord(i, 1)) * dim[0] + coord(i, 0);
        ++start[size_t(cell_of[size_t(i)] + 1)];
    }
    for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
    std::vector<int64_t> fill(start.begin(), start.end() - 1), members(static_cast<size_t>(n));
    for (int64_t i = 0; i < n; ++i) members[size_t(fill[size_t(cell_of[size_t(i)])]++)] = i;
    std::vector<int64_t> comp(size_t(n), -1);
    std::vector<int64_t> stack;
    for (int64_t s = 0; s < n; ++s) {
        if (comp[size_t(s)] >= 0) continue;
        out.emplace_back();
        comp[size_t(s)] = int64_t(out.size()) - 1;
        stack.assign(1, s);
        while (!stack.empty()) {
            const int64_t a = stack.back();
            stack.pop_back();
            out.back().push_back(a);
            const int64_t cx = coord(a, 0), cy = coord(a, 1), cz = coord(a, 2);
            for (int64_t z = std::max<int64_t>(0, cz - 1); z <= std::min(dim[2] - 1, cz + 1); ++z)
                for (int64_t y = std::max<int64_t>(0, cy - 1); y <= std::min(dim[1] - 1, cy + 1); ++y) {
                    const int64_t row = (z * dim[1] + y) * dim[0];
                    const int64_t x0 = std::max<int64_t>(0, cx - 1), x1 = std::min(dim[0] - 1, cx + 1);
                    for (int64_t k = start[size_t(row + x0)]; k < start[size_t(row + x1 + 1)]; ++k) {
                        const int64_t b = members[size_t(k)];
                        if (comp[size_t(b)] < 0 && (pts.row(a) - pts.row(b)).squaredNorm() < r2) {
                            comp[size_t(b)] = comp[size_t(s)];
                            stack.push_back(b);
                        }
                    }
                }
        }
    }
    for (auto& c : out) std::sort(c.begin(), c.end());
    std::stable_sort(out.begin(), out.end(),
                     [](const auto& a, const auto& b) { return a.size() > b.size(); });
    return out;
}

bool fit_plane(const DepthImage& dimg, int x0, int y0, int x1, int y1, double tol_mm, Plane* out,
               int max_samples, int iterations) {
    G2L_CHECK(dimg.depth_mm && dimg.K.width > 0 && dimg.K.height > 0 && dimg.K.fx > 0 &&
                  dimg.K.fy > 0,
              "fit_plane: the depth image needs a buffer, a size and focal lengths");
    G2L_CHECK(tol_mm > 0 && max_samples >= 3 && iterations >= 1, "fit_plane: invalid options (tol_mm ",
              tol_mm, ", max_samples ", max_samples, ", iterations ", iterations, ")");
    const Intrinsics& K = dimg.K;
    x0 = std::max(0, x0); y0 = std::max(0, y0);
    x1 = std::min(K.width, x1); y1 = std::min(K.height, y1);
    if (x1 <= x0 || y1 <= y0) return false;
    const double step = std::max(1.0, std::sqrt(double(x1 - x0) * double(y1 - y0) / max_samples));
    std::vector<Eigen::Vector3d> P;
    for (double v = y0 + 0.5 * step; v < y1; v += step)
        for (double u = x0 + 0.5 * step; u < x1; u += step) {
            const int iu = int(u), iv = int(v);
            const float z = dimg.depth_mm[int64_t(iv) * K.width + iu];
            if (!(z > 0.f) || !std::isfinite(z)) continue;
            P.emplace_back((iu - K.cx) * z / K.fx, (iv - K.cy) * z / K.fy, z);
        }
    const int64_t n = int64_t(P.size());
    if (n < 3) return false;
    uint64_t state = 0x9E3779B97F4A7C15ULL;
    auto draw = [&]() {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return int64_t((state >> 33) % uint64_t(n));
    };
    // The draws in order, then each draw's plane counted on its own (in parallel); the first
    // draw with the most points wins.
    std::vector<std::array<int64_t, 3>> draws(size_t(std::max(0, iterations)));
    for (auto& t : draws) t = {draw(), draw(), draw()};
    std::vector<Eigen::Vector3d> normal(draws.size());
    std::vector<int64_t> counts(draws.size(), -1);
    for_each_index(int64_t(draws.size()), [&](int64_t it) {
        const auto& t = draws[size_t(it)];
        const Eigen::Vector3d &a = P[size_t(t[0])], &b = P[size_t(t[1])], &c = P[size_t(t[2])];
        Eigen::Vector3d nrm = (b - a).cross(c - a);
        if (nrm.norm() < 1e-6) return;
        nrm.normalize();
        const double d = -nrm.dot(a);
        int64_t count = 0;
        for (const auto& p : P) count += std::abs(nrm.dot(p) + d) <= tol_mm;
        normal[size_t(it)] = nrm;
        counts[size_t(it)] = count;
    });
    Eigen::Vector3d best_n = Eigen::Vector3d::Zero();
    double best_d = 0;
    int64_t best_count = -1;
    for (size_t it = 0; it < draws.size(); ++it)
        if (counts[it] > best_count) {
            best_count = counts[it];
            best_n = normal[it];
            best_d = -best_n.dot(P[size_t(draws[it][0])]);
        }
    if (best_count < 3) return false;
    // Least-squares refit to the inliers: the normal is the direction of least spread.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> in;
    for (const auto& p : P)
        if (std::abs(best_n.dot(p) + best_d) <= tol_mm) in.push_back(p);
    for (const auto& p : in) mean += p;
    mean /= double(in.size());
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (const auto& p : in) C += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C);
    Eigen::Vector3d nrm = eig.eigenvectors().col(0).normalized();
    if (nrm.dot(best_n) < 0) nrm = -nrm;
    double d = -nrm.dot(mean);
    if (d < 0) { nrm = -nrm; d = -d; }
    int64_t count = 0;
    for (const auto& p : P) count += std::abs(nrm.dot(p) + d) <= tol_mm;
    out->n = nrm;
    out->d = d;
    out->inlier_frac = double(count) / double(n);
    return true;
}

double fit_error(const ModelKdTree& tree, const Points& obs, const Pose& pose, double cap_mm) {
    return fit_with(tree, nullptr, true, obs, pose, cap_mm);
}

ClosestPointGrid::ClosestPointGrid(const ModelKdTree& tree, double cell_mm, double margin_mm,
                                   int64_t max_cells) {
    G2L_CHECK(std::isfinite(cell_mm) && cell_mm > 0, "ClosestPointGrid: cell_mm must be > 0, got ",
              cell_mm);
    G2L_CHECK(std::isfinite(margin_mm) && margin_mm >= 0,
              "ClosestPointGrid: margin_mm must be >= 0, got ", margin_mm);
    const Points& p = tree.points();
    const Eigen::Vector3f lo = p.colwise().minCoeff().transpose().array() - float(margin_mm);
    const Eigen::Vector3f hi = p.colwise().maxCoeff().transpose().array() + float(margin_mm);
    const auto count = [&](int a) { return std::max<int64_t>(1, int64_t(std::ceil((hi[a] - lo[a]) / cell_mm))); };
    const int64_t nx = count(0), ny = count(1), nz = count(2);
    const int64_t limit = std::min<int64_t>(max_cells, INT32_MAX);
    G2L_CHECK(double(nx) * double(ny) * double(nz) <= double(limit), "ClosestPointGrid: ", nx,
              " x ", ny, " x ", nz, " cells of ", cell_mm, " mm exceed the limit of ", limit,
              " (use larger cells)");
    lo_ = lo;
    cell_ = cell_mm;
    margin_ = margin_mm;
    inv_cell_ = float(1.0 / cell_mm);
    nx_ = int(nx), ny_ = int(ny), nz_ = int(nz);
    tree_points_ = tree.size();
    // The buckets: cubes of at least 4 mm (a couple of the 2 mm surface samples across), over
    // the points' box, at most ~2^18 of them.
    {
        const Eigen::Vector3f plo = p.colwise().minCoeff().transpose();
        const Eigen::Vector3f ext = p.colwise().maxCoeff().transpose() - plo;
        double b = 4.0;
        while (double(int64_t(ext.x() / b) + 1) * double(int64_t(ext.y() / b) + 1) *
                   double(int64_t(ext.z() / b) + 1) > double(1 << 18))
            b *= 1.25;
        bucket_ = b;
        bucket_lo_ = plo;
        inv_bucket_ = float(1.0 / b);
        bnx_ = int64_t(ext.x() * inv_bucket_) + 1;
        bny_ = int64_t(ext.y() * inv_bucket_) + 1;
        bnz_ = int64_t(ext.z() * inv_bucket_) + 1;
        const int64_t np = p.rows();
        std::vector<int64_t> of(static_cast<size_t>(np));
        bucket_start_.assign(size_t(bnx_ * bny_ * bnz_ + 1), 0);
        for (int64_t i = 0; i < np; ++i) {
            int64_t c[3];
            const int64_t nb[3] = {bnx_, bny_, bnz_};
            for (int a = 0; a < 3; ++a)
                c[a] = std::clamp<int64_t>(int64_t((p(i, a) - plo[a]) * inv_bucket_), 0, nb[a] - 1);
            of[size_t(i)] = (c[2] * bny_ + c[1]) * bnx_ + c[0];
            ++bucket_start_[size_t(of[size_t(i)] + 1)];
        }
        for (size_t k = 1; k < bucket_start_.size(); ++k) bucket_start_[k] += bucket_start_[k - 1];
        std::vector<int32_t> fill(bucket_start_.begin(), bucket_start_.end() - 1);
        bucket_row_.resize(size_t(np));
        bucket_pts_.resize(size_t(3 * np));  // x of every point, then y, then z
        for (int64_t i = 0; i < np; ++i) {  // rows ascending within each bucket
            const int32_t at = fill[size_t(of[size_t(i)])]++;
            bucket_row_[size_t(at)] = int32_t(i);
            for (int a = 0; a < 3; ++a) bucket_pts_[size_t(a * np + at)] = p(i, a);
        }
    }
    cells_.assign(size_t(nx * ny * nz), 0);
    const Layout g = layout();
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y)
            for (int64_t x = 0; x < nx; ++x) {
                const Eigen::Vector3f c = lo + Eigen::Vector3f(float(x) + 0.5f, float(y) + 0.5f,
                                                               float(z) + 0.5f) * float(cell_mm);
                int idx = 0;
                tree.nearest(c, &idx);
                cells_[size_t(g.offset(int(x), int(y), int(z)))] = int32_t(idx);
            }
}

float ClosestPointGrid::nearest_below(const Eigen::Vector3f& x, float bound_mm, int* index) const {
    if (bucket_start_.empty() || !(bound_mm > 0.f)) return std::numeric_limits<float>::infinity();
    int64_t lo[3], hi[3];
    const int64_t n[3] = {bnx_, bny_, bnz_};
    for (int a = 0; a < 3; ++a) {
        const float f0 = (x[a] - bound_mm - bucket_lo_[a]) * inv_bucket_;
        const float f1 = (x[a] + bound_mm - bucket_lo_[a]) * inv_bucket_;
        if (!(f1 >= 0.f) || !(f0 < float(n[a]))) return std::numeric_limits<float>::infinity();
        lo[a] = f0 > 0.f ? int64_t(f0) : 0;
        hi[a] = std::min<int64_t>(n[a] - 1, int64_t(f1));
    }
    // The squared distance as the k-d tree sums it (x, then y, then z), so that the distances
    // and the choice between them are the same numbers; the first point at the least distance
    // in the order of the buckets' rows (as a point-by-point scan keeps it). Each row's points
    // are contiguous (x, y and z apart): with AVX-512, 16 distances at a time.
    float best = bound_mm * bound_mm;
    int found = -1;
    const int64_t np = int64_t(bucket_row_.size());
    const float *px = bucket_pts_.data(), *py = px + np, *pz = py + np;
#if defined(__AVX512F__)
    const __m512 vx = _mm512_set1_ps(x[0]), vy = _mm512_set1_ps(x[1]), vz = _mm512_set1_ps(x[2]);
    __m512 vbest = _mm512_set1_ps(best);
#endif
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y) {
            const int64_t row = (z * bny_ + y) * bnx_;
            const int32_t end = bucket_start_[size_t(row + hi[0] + 1)];
            int32_t i = bucket_start_[size_t(row + lo[0])];
#if defined(__AVX512F__)
            for (; i < end; i += 16) {
                const __mmask16 k = end - i >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << (end - i)) - 1);
                const __m512 dx = _mm512_sub_ps(vx, _mm512_maskz_loadu_ps(k, px + i));
                const __m512 dy = _mm512_sub_ps(vy, _mm512_maskz_loadu_ps(k, py + i));
                const __m512 dz = _mm512_sub_ps(vz, _mm512_maskz_loadu_ps(k, pz + i));
                __m512 s = _mm512_mul_ps(dx, dx);
                s = _mm512_fmadd_ps(dy, dy, s);
                s = _mm512_fmadd_ps(dz, dz, s);
                const __mmask16 lt = _mm512_mask_cmp_ps_mask(k, s, vbest, _CMP_LT_OQ);
                if (!lt) continue;
                best = _mm512_mask_reduce_min_ps(lt, s);
                vbest = _mm512_set1_ps(best);
                const __mmask16 eq = _mm512_mask_cmp_ps_mask(lt, s, vbest, _CMP_EQ_OQ);
                found = i + __builtin_ctz(unsigned(eq));
            }
#else
            for (; i < end; ++i) {
                const float dx = x[0] - px[i], dy = x[1] - py[i], dz = x[2] - pz[i];
                float d2 = 0.f;
                d2 += dx * dx;
                d2 += dy * dy;
                d2 += dz * dz;
                if (d2 < best) best = d2, found = i;
            }
#endif
        }
    if (found < 0) return std::numeric_limits<float>::infinity();
    *index = bucket_row_[size_t(found)];
    return std::sqrt(best);
}

ClosestPointGrid ClosestPointGrid::for_refine(const ModelKdTree& tree, const ModelInfo& info,
                                              const RefineOptions& opt) {
    G2L_CHECK(std::isfinite(info.diameter) && info.diameter > 0,
              "ClosestPointGrid::for_refine: model diameter must be > 0, got ", info.diameter);
    const double cell = std::clamp(info.diameter / 80.0, 1.0, 4.0);
    return ClosestPointGrid(tree, cell, opt.inlier_frac * info.diameter);
}

double free_space_violation(const Points& model_pts, const Pose& pose, const DepthImage& dimg,
                            double tol_mm) {
    const Intrinsics& K = dimg.K;
    const Eigen::Matrix3f R = pose.R.cast<float>();
    const Eigen::Vector3f t = pose.t.cast<float>();
    int64_t viol = 0, seen = 0;
    for (int64_t i = 0; i < model_pts.rows(); ++i) {
        const Eigen::Vector3f q = R * model_pts.row(i).transpose() + t;
        if (!(q.z() > 1.f)) continue;
        const int u = int(std::lround(K.fx * q.x() / q.z() + K.cx));
        const int v = int(std::lround(K.fy * q.y() / q.z() + K.cy));
        if (u < 0 || v < 0 || u >= K.width || v >= K.height) continue;
        const float z = dimg.depth_mm[int64_t(v) * K.width + u];
        if (!(z > 0.f) || !std::isfinite(z)) continue;
        if (q.z() > z + tol_mm) continue;  // hidden behind the measured surface
        ++seen;
        viol += q.z() < z - tol_mm;
    }
    return seen ? double(viol) / double(seen) : 0.0;
}

namespace {

// The inputs refine_pose refuses, named (a grid that is empty counts as none).
void check_refine_inputs(const char* who, const ModelKdTree& tree, const ModelInfo& info,
                         const Points& obs_all, const Pose& init, const RefineOptions& opt,
                         const DepthImage* depth, const ClosestPointGrid* grid) {
    G2L_CHECK(std::isfinite(info.diameter) && info.diameter > 0,
              who, ": model diameter must be > 0, got ", info.diameter);
    G2L_CHECK(obs_all.rows() >= 3, who, ": need at least 3 observed points, got ",
              obs_all.rows());
    G2L_CHECK(init.R.allFinite() && init.t.allFinite(), who, ": the ",
              std::string(who) == "refine_pose" ? "initial " : "", "pose is not finite");
    G2L_CHECK(opt.iterations >= 0 && opt.coarse_iterations >= 0 && opt.max_points >= 3 &&
                  opt.inlier_frac > 0 && opt.axis_steps >= 1 && opt.switch_ratio > 0 &&
                  opt.finalists >= 0 && opt.model_points >= 1 && opt.free_space_frac > 0 &&
                  opt.free_space_weight >= 0,
              who, ": invalid options (iterations ", opt.iterations, ", coarse_iterations ",
              opt.coarse_iterations, ", max_points ", opt.max_points, ", inlier_frac ",
              opt.inlier_frac, ", axis_steps ", opt.axis_steps, ", switch_ratio ",
              opt.switch_ratio, ", finalists ", opt.finalists, ", model_points ",
              opt.model_points, ", free_space_frac ", opt.free_space_frac,
              ", free_space_weight ", opt.free_space_weight, ")");
    const int64_t n_all = obs_all.rows();
    for (int64_t i = 0; i < n_all; ++i)
        G2L_CHECK(obs_all.row(i).allFinite(), who, ": observed point ", i, " is not finite");
    G2L_CHECK(!depth || (depth->depth_mm && depth->K.width > 0 && depth->K.height > 0 &&
                         depth->K.fx > 0 && depth->K.fy > 0),
              who, ": the depth image needs a buffer, a size and focal lengths");
    G2L_CHECK(std::isfinite(opt.cluster_frac) && opt.cluster_frac >= 0 &&
                  std::isfinite(opt.cluster_min_share) && opt.cluster_min_share >= 0 &&
                  opt.cluster_min_share <= 1,
              who, ": invalid cluster options (cluster_frac ", opt.cluster_frac,
              ", cluster_min_share ", opt.cluster_min_share, ")");
    G2L_CHECK(!opt.support_plane || (opt.plane_tol_mm > 0 && opt.plane_depth_mm >= 0 &&
                                     opt.plane_region >= 0 && opt.plane_min_inliers >= 0 &&
                                     opt.plane_min_inliers <= 1),
              who, ": invalid support-plane options (plane_tol_mm ", opt.plane_tol_mm,
              ", plane_depth_mm ", opt.plane_depth_mm, ", plane_region ", opt.plane_region,
              ", plane_min_inliers ", opt.plane_min_inliers, ")");
    G2L_CHECK(std::isfinite(opt.alt_min_deg) && opt.alt_min_deg >= 0, who,
              ": alt_min_deg must be finite and >= 0, got ", opt.alt_min_deg);
    G2L_CHECK(opt.polish_iterations >= 0, who, ": polish_iterations must be >= 0, got ",
              opt.polish_iterations);
    G2L_CHECK(!grid || grid->margin_mm() >= opt.inlier_frac * info.diameter * (1 - 1e-9),
              who, ": the grid's margin (", grid ? grid->margin_mm() : 0.0,
              " mm) is below the inlier cap (", opt.inlier_frac * info.diameter,
              " mm): build it with ClosestPointGrid::for_refine");
    G2L_CHECK(!grid || grid->tree_points() == tree.size(),
              who, ": the grid was built over a tree of ", grid ? grid->tree_points() : 0,
              " points, this tree has ", tree.size());
}

// The support plane around the observed points' image box (grown by plane_region), when the
// depth shows one with enough inliers.
bool find_support_plane(const Points& obs_all, const DepthImage& depth, const RefineOptions& opt,
                        Plane* plane) {
    const Intrinsics& K = depth.K;
    double u0 = 1e300, v0 = 1e300, u1 = -1e300, v1 = -1e300;
    for (int64_t i = 0; i < obs_all.rows(); ++i) {
        const double z = obs_all(i, 2);
        if (!(z > 1.0)) continue;
        const double u = K.fx * obs_all(i, 0) / z + K.cx, v = K.fy * obs_all(i, 1) / z + K.cy;
        u0 = std::min(u0, u); u1 = std::max(u1, u);
        v0 = std::min(v0, v); v1 = std::max(v1, v);
    }
    const double gu = opt.plane_region * (u1 - u0), gv = opt.plane_region * (v1 - v0);
    return u1 >= u0 &&
           fit_plane(depth, int(std::floor(u0 - gu)), int(std::floor(v0 - gv)),
                     int(std::ceil(u1 + gu)) + 1, int(std::ceil(v1 + gv)) + 1, opt.plane_tol_mm,
                     plane) &&
           plane->inlier_frac >= opt.plane_min_inliers;
}

// The point sets refine_pose searches: all the observed points, then (when they split into
// more than one Euclidean cluster, points closer than cluster_frac of the diameter joined: the
// segmentation may have taken a neighbouring object too) each cluster holding at least
// cluster_min_share of them, with its rows in obs_all.
std::vector<std::vector<int64_t>> cluster_sets(const Points& obs_all, const ModelInfo& info,
                                               const RefineOptions& opt) {
    if (opt.cluster_frac <= 0) return {};
    std::vector<std::vector<int64_t>> clusters =
        euclidean_clusters(obs_all, opt.cluster_frac * info.diameter);
    if (clusters.size() < 2) return {};
    std::vector<std::vector<int64_t>> out;
    for (auto& rows : clusters)
        out.push_back(rows.size() < 3 || double(rows.size()) < opt.cluster_min_share * double(obs_all.rows())
                          ? std::vector<int64_t>{}
                          : std::move(rows));
    return out;
}

// At most model_points of the tree's points, evenly strided: the model points the penalties
// project.
Points strided_model_points(const ModelKdTree& tree, int model_points) {
    const Points& tp = tree.points();
    const int64_t nm = std::min<int64_t>(tp.rows(), std::max(1, model_points));
    Points sub(nm, 3);
    for (int64_t i = 0; i < nm; ++i) sub.row(i) = tp.row(i * tp.rows() / nm);
    return sub;
}

// The refinement's cost of `pose` given its fit: fit + free_space_weight * cap * (the fraction
// of model_sub violating free space + the fraction beneath the support plane, when one was
// found); the violating fraction to *viol.
double penalised(const Points& model_sub, const Pose& p, double fit, const DepthImage* depth,
                 const Plane* plane, const RefineOptions& opt, double diameter, double* viol) {
    *viol = depth ? free_space_violation(model_sub, p, *depth, opt.free_space_frac * diameter) : 0.0;
    if (plane) {  // model points beneath the support plane
        const int64_t nm = model_sub.rows();
        const Eigen::Vector3d pn = p.R.transpose() * plane->n;
        const double pd = plane->n.dot(p.t) + plane->d;
        int64_t under = 0;
        for (int64_t i = 0; i < nm; ++i)
            under += pn.dot(model_sub.row(i).transpose().cast<double>()) + pd < -opt.plane_depth_mm;
        *viol += double(under) / double(nm);
    }
    return fit + opt.free_space_weight * opt.inlier_frac * diameter * *viol;
}

// The observed points a search uses: at most max_points, evenly strided.
Points strided_observed(const Points& src, int max_points) {
    const int64_t n_src = src.rows(), n = std::min<int64_t>(n_src, max_points);
    Points obs(n, 3);
    for (int64_t i = 0; i < n; ++i) obs.row(i) = src.row(i * n_src / n);
    return obs;
}

}  // namespace

double pose_cost(const ModelKdTree& tree, const ModelInfo& info, const Points& obs,
                 const Pose& pose, const RefineOptions& opt, const DepthImage* depth) {
    check_refine_inputs("pose_cost", tree, info, obs, pose, opt, depth, nullptr);
    Plane plane;
    const bool has_plane = depth && opt.support_plane && find_support_plane(obs, *depth, opt, &plane);
    double viol = 0;
    return penalised(strided_model_points(tree, opt.model_points), pose,
                     fit_error(tree, strided_observed(obs, opt.max_points), pose,
                               opt.inlier_frac * info.diameter),
                     depth, has_plane ? &plane : nullptr, opt, info.diameter, &viol);
}

RefineResult refine_pose(const ModelKdTree& tree, const ModelInfo& info, const Points& obs_all,
                         const Pose& init, const RefineOptions& opt, const DepthImage* depth,
                         const Points* normals, const ClosestPointGrid* grid,
                         const std::vector<SymmetryTransform>* syms) {
    if (grid && grid->empty()) grid = nullptr;  // an empty grid is no grid
    check_refine_inputs("refine_pose", tree, info, obs_all, init, opt, depth, grid);
    const int64_t n_all = obs_all.rows();
    RefineResult base;
    base.observed = int(n_all);
    Plane plane;
    if (depth && opt.support_plane) base.plane = find_support_plane(obs_all, *depth, opt, &plane);
    G2L_CHECK(!normals || normals->rows() == tree.size(), "refine_pose: ", normals ? normals->rows() : 0,
              " normals for ", tree.size(), " model points");
    // What every searched point set shares: the turns, the model points projected for the
    // penalties, and the cost (capped fit + the free-space and support-plane penalties).
    const double cap = opt.inlier_frac * info.diameter;
    const Eigen::Vector3d c = info.min + 0.5 * info.size;
    const std::vector<Eigen::Matrix3d> T =
        opt.hypotheses ? turns(opt.axis_steps) : std::vector<Eigen::Matrix3d>{Eigen::Matrix3d::Identity()};
    const Points model_sub = strided_model_points(tree, opt.model_points);
    auto cost = [&](const Pose& p, double fit, double* viol) {
        return penalised(model_sub, p, fit, depth, base.plane ? &plane : nullptr, opt,
                         info.diameter, viol);
    };
    // The search from the networks' pose and its turns over one set of observed points.
    auto search = [&](const Points& src) {
        RefineResult r = base;
        const Points obs = strided_observed(src, opt.max_points);
        Icp icp{tree, obs, normals, cap, {}, {}, {}, {}, {}};
        struct Hyp { Pose pose; double fit; int index; double viol = 0; };
        // Each start is independent (its own copy of the ICP scratch): the starts run in
        // parallel; the result does not depend on the thread count.
        std::vector<Hyp> hyps(T.size());
        for_each_index(int64_t(T.size()), [&](int64_t h) {
            // init composed with the turn about the box centre: p -> R0 (Rs (p - c) + c) + t0.
            Icp own = icp;
            Hyp& y = hyps[size_t(h)];
            y.pose.R = init.R * T[size_t(h)];
            y.pose.t = init.R * (c - T[size_t(h)] * c) + init.t;
            y.index = int(h);
            y.fit = cost(y.pose, own.run(y.pose, opt.coarse_iterations, grid, false), &y.viol);
        });
        // The network's start and the best turned starts get the full iterations.
        std::vector<Hyp> rest(hyps.begin() + 1, hyps.end());
        std::stable_sort(rest.begin(), rest.end(), [](const Hyp& a, const Hyp& b) { return a.fit < b.fit; });
        std::vector<Hyp> final{hyps[0]};
        for (size_t i = 0; i < std::min<size_t>(size_t(std::max(0, opt.finalists)), rest.size()); ++i) final.push_back(rest[i]);
        for_each_index(int64_t(final.size()), [&](int64_t i) {
            Icp own = icp;
            Hyp& y = final[size_t(i)];
            // With a grid the exact steps follow and measure the fit: the grid's fit of the
            // pose they start from is not needed.
            double fit = own.run(y.pose, opt.iterations, grid, false, /*want_fit=*/!grid);
            if (grid) fit = own.run(y.pose, opt.polish_iterations, grid, true);  // exact steps and fit
            y.fit = cost(y.pose, fit, &y.viol);
        });
        r.pose = final[0].pose;
        r.fit_mm = r.start_fit_mm = final[0].fit;
        r.violation = final[0].viol;
        r.hypotheses = int(T.size());
        for (size_t i = 1; i < final.size(); ++i)
            if (final[i].fit < opt.switch_ratio * final[0].fit && final[i].fit < r.fit_mm) {
                r.pose = final[i].pose;
                r.fit_mm = final[i].fit;
                r.violation = final[i].viol;
                r.hypothesis = final[i].index;
            }
        // The best distinct pose among the finalists: a rotation away from the winner's, also
        // modulo the model's symmetries when they are given.
        for (const Hyp& y : final)
            if ((r.alt_fit_mm < 0 || y.fit < r.alt_fit_mm) &&
                (syms ? rotation_error_sym_deg(y.pose.R, r.pose.R, *syms)
                      : rotation_error_deg(y.pose.R, r.pose.R)) > opt.alt_min_deg)
                r.alt_fit_mm = y.fit;
        return r;
    };
    // The searches over all the points and over each cluster run together; the lowest cost
    // (fit plus penalties) wins, the search over all the points on ties, then the larger cluster.
    const std::vector<std::vector<int64_t>> clusters = cluster_sets(obs_all, info, opt);
    std::vector<Points> subsets(clusters.size());
    std::vector<RefineResult> found(clusters.size() + 1);
    for_each_index(int64_t(found.size()), [&](int64_t k) {
        if (k == 0) {
            found[0] = search(obs_all);
            return;
        }
        const auto& rows = clusters[size_t(k - 1)];
        if (rows.empty()) return;
        Points& sub = subsets[size_t(k - 1)];
        sub.resize(int64_t(rows.size()), 3);
        for (size_t i = 0; i < rows.size(); ++i) sub.row(int64_t(i)) = obs_all.row(rows[i]);
        found[size_t(k)] = search(sub);
        found[size_t(k)].cluster = int(k - 1);
        found[size_t(k)].observed = int(rows.size());
    });
    RefineResult best = found[0];
    for (size_t k = 1; k < found.size(); ++k)
        if (!clusters[k - 1].empty() && found[k].fit_mm < best.fit_mm) best = found[k];
    return best;
}

}  // namespace g2l::geom
