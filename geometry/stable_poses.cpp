// SPDX-License-Identifier: MIT
#include "geometry/stable_poses.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.h"

namespace g2l::geom {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Height of the centre of mass above the plane when gravity points along d (unit).
double support(const std::vector<Eigen::Vector3d>& v, const Eigen::Vector3d& d) {
    double h = -1e300;
    for (const auto& p : v) h = std::max(h, p.dot(d));
    return h;
}

// Any unit vector orthogonal to d.
Eigen::Vector3d orthogonal(const Eigen::Vector3d& d) {
    const Eigen::Vector3d a = std::fabs(d.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    return d.cross(a).normalized();
}

}  // namespace

Eigen::Vector3d centre_of_mass(const Mesh& mesh) {
    G2L_CHECK(mesh.vertices.rows() > 0, "centre_of_mass: mesh '", mesh.path, "' has no vertices");
    const auto& V = mesh.vertices;
    const Eigen::Vector3d mean = V.cast<double>().colwise().mean().transpose();
    if (mesh.faces.rows() == 0) return mean;
    double vol = 0, area = 0;
    Eigen::Vector3d cv = Eigen::Vector3d::Zero(), ca = Eigen::Vector3d::Zero();
    for (int64_t f = 0; f < mesh.faces.rows(); ++f) {
        const int i0 = mesh.faces(f, 0), i1 = mesh.faces(f, 1), i2 = mesh.faces(f, 2);
        if (i0 < 0 || i1 < 0 || i2 < 0 || i0 >= V.rows() || i1 >= V.rows() || i2 >= V.rows())
            continue;
        // Relative to the vertex mean: better conditioned for models far from the origin.
        const Eigen::Vector3d a = V.row(i0).cast<double>().transpose() - mean;
        const Eigen::Vector3d b = V.row(i1).cast<double>().transpose() - mean;
        const Eigen::Vector3d c = V.row(i2).cast<double>().transpose() - mean;
        const double v6 = a.dot(b.cross(c));  // 6 x signed volume of (0, a, b, c)
        vol += v6;
        cv += v6 * (a + b + c) / 4.0;
        const double ar = 0.5 * (b - a).cross(c - a).norm();
        area += ar;
        ca += ar * (a + b + c) / 3.0;
    }
    // A closed surface encloses |vol| / 6; "almost none" is judged against the bounding box.
    const Eigen::Vector3d ext =
        (V.colwise().maxCoeff() - V.colwise().minCoeff()).cast<double>().transpose();
    const double box = std::max(1e-12, ext.x() * ext.y() * ext.z());
    if (std::fabs(vol) / 6.0 > 1e-3 * box) return mean + cv / vol;
    if (area > 0) return mean + ca / area;
    return mean;
}

namespace {

// Fibonacci sphere: n equal-area drop directions.
std::vector<Eigen::Vector3d> fibonacci_sphere(int n) {
    std::vector<Eigen::Vector3d> dir(static_cast<size_t>(n));
    const double golden = kPi * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(std::max(0.0, 1 - z * z));
        dir[size_t(i)] = Eigen::Vector3d(r * std::cos(golden * i), r * std::sin(golden * i), z);
    }
    return dir;
}

// The basin of each direction: where steepest descent of the support height h over the graph of
// each direction's k nearest (brute force; a few thousand directions) ends, a local minimum —
// the face the object settles on when dropped that way up.
std::vector<int> descent_basins(const std::vector<Eigen::Vector3d>& dir,
                                const std::vector<double>& h, int k) {
    const int N = int(dir.size());
    std::vector<std::vector<int>> nb(static_cast<size_t>(N));
    std::vector<std::pair<double, int>> cand(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) {
        for (int j = 0; j < N; ++j) cand[size_t(j)] = {-dir[size_t(i)].dot(dir[size_t(j)]), j};
        std::partial_sort(cand.begin(), cand.begin() + k + 1, cand.end());
        for (int q = 1; q <= k; ++q) nb[size_t(i)].push_back(cand[size_t(q)].second);
    }
    std::vector<int> basin(static_cast<size_t>(N), -1);
    for (int i = 0; i < N; ++i) {
        int c = i;
        std::vector<int> path;
        while (basin[size_t(c)] < 0) {
            path.push_back(c);
            int best = c;
            for (int j : nb[size_t(c)])
                if (h[size_t(j)] < h[size_t(best)] - 1e-9) best = j;
            if (best == c) {
                basin[size_t(c)] = c;
                break;
            }
            c = best;
        }
        for (int p : path) basin[size_t(p)] = basin[size_t(c)];
    }
    return basin;
}

// A minimum of the support height refined by a pattern search on the sphere (8 directions,
// the step halved until 1e-4 degrees): the sampled directions are ~2-4 degrees apart.
void refine_minimum(const std::vector<Eigen::Vector3d>& v, Eigen::Vector3d* dp, double* hp) {
    Eigen::Vector3d d = *dp;
    double hd = *hp;
    double step = 4.0 * kPi / 180.0;
    while (step > 1e-4 * kPi / 180.0) {
        const Eigen::Vector3d u = orthogonal(d), w = d.cross(u);
        bool moved = false;
        for (int a = 0; a < 8 && !moved; ++a) {
            const double ang = a * kPi / 4.0;
            const Eigen::Vector3d t = std::cos(ang) * u + std::sin(ang) * w;
            const Eigen::Vector3d nd = (std::cos(step) * d + std::sin(step) * t).normalized();
            const double nh = support(v, nd);
            if (nh < hd - 1e-12) {
                d = nd;
                hd = nh;
                moved = true;
            }
        }
        if (!moved) step *= 0.5;
    }
    *dp = d;
    *hp = hd;
}

}  // namespace

std::vector<StablePose> stable_poses(const Mesh& mesh, const Eigen::Vector3d& com,
                                     const StablePoseOptions& opt) {
    G2L_CHECK(mesh.vertices.rows() > 0, "stable_poses: mesh '", mesh.path, "' has no vertices");
    G2L_CHECK(opt.directions >= 100, "stable_poses: directions must be >= 100, got ", opt.directions);
    G2L_CHECK(opt.neighbours >= 3 && opt.neighbours < opt.directions,
              "stable_poses: neighbours must be in [3, directions), got ", opt.neighbours);
    G2L_CHECK(opt.merge_deg > 0 && opt.merge_deg < 90, "stable_poses: merge_deg must be in (0, 90), got ",
              opt.merge_deg);
    G2L_CHECK(opt.min_probability >= 0 && opt.min_probability < 1,
              "stable_poses: min_probability must be in [0, 1), got ", opt.min_probability);
    G2L_CHECK(opt.max_vertices > 0, "stable_poses: max_vertices must be > 0, got ", opt.max_vertices);
    const int64_t nv = mesh.vertices.rows();
    const int64_t stride = std::max<int64_t>(1, (nv + opt.max_vertices - 1) / opt.max_vertices);
    std::vector<Eigen::Vector3d> v;
    for (int64_t i = 0; i < nv; i += stride) v.push_back(mesh.vertices.row(i).cast<double>().transpose() - com);

    const int N = opt.directions;
    const std::vector<Eigen::Vector3d> dir = fibonacci_sphere(N);
    std::vector<double> h(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) h[size_t(i)] = support(v, dir[size_t(i)]);
    const std::vector<int> basin = descent_basins(dir, h, opt.neighbours);
    // Each minimum, refined by a pattern search on the sphere, with its basin's share.
    std::vector<StablePose> found;
    std::vector<int> count(static_cast<size_t>(N), 0);
    for (int i = 0; i < N; ++i) ++count[size_t(basin[size_t(i)])];
    for (int m = 0; m < N; ++m) {
        if (basin[size_t(m)] != m) continue;
        Eigen::Vector3d d = dir[size_t(m)];
        double hd = h[size_t(m)];
        refine_minimum(v, &d, &hd);
        StablePose p;
        p.down = d.cast<float>();
        p.height = hd;
        p.probability = double(count[size_t(m)]) / N;
        bool merged = false;
        for (StablePose& q : found) {
            if (q.down.cast<double>().dot(d) > std::cos(opt.merge_deg * kPi / 180.0)) {
                q.probability += p.probability;
                merged = true;
                break;
            }
        }
        if (!merged) found.push_back(p);
    }
    std::sort(found.begin(), found.end(),
              [](const StablePose& a, const StablePose& b) { return a.probability > b.probability; });
    std::vector<StablePose> out;
    double total = 0;
    for (const StablePose& p : found)
        if (p.probability >= opt.min_probability || out.empty()) out.push_back(p), total += p.probability;
    for (StablePose& p : out) p.probability /= total;
    return out;
}

Eigen::Matrix3d resting_rotation(const StablePose& pose) {
    return Eigen::Quaterniond::FromTwoVectors(pose.down.cast<double>().normalized(),
                                              -Eigen::Vector3d::UnitZ())
        .toRotationMatrix();
}

}  // namespace g2l::geom
