// SPDX-License-Identifier: MIT
#include "geometry/crop.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace g2l::geom {

CropKind parse_crop(const std::string& text, const std::string& what) {
    if (text == "sphere") return CropKind::sphere;
    if (text == "frustum") return CropKind::frustum;
    if (text == "slab") return CropKind::slab;
    G2L_CHECK(false, what, " must be sphere, frustum or slab, got '", text, "'");
    return CropKind::sphere;
}

const char* to_string(CropKind c) {
    switch (c) {
        case CropKind::sphere: return "sphere";
        case CropKind::frustum: return "frustum";
        case CropKind::slab: return "slab";
    }
    return "unknown crop";
}

std::vector<int> crop_indices(CropKind crop, const Points& pts, const Eigen::Vector3d& centre,
                              double radius) {
    G2L_CHECK(crop == CropKind::sphere || crop == CropKind::slab || crop == CropKind::frustum,
              "crop_indices: unknown crop kind ", int(crop));
    const int n = static_cast<int>(pts.rows());
    std::vector<int> kept;
    if (crop == CropKind::frustum) {
        kept.resize(size_t(n));
        for (int i = 0; i < n; ++i) kept[size_t(i)] = i;
        return kept;
    }
    G2L_CHECK(std::isfinite(radius) && radius > 0, "crop_indices: radius must be finite and > 0, got ",
              radius);
    G2L_CHECK(centre.allFinite(), "crop_indices: centre (", centre.x(), ", ", centre.y(), ", ",
              centre.z(), ") is not finite");
    kept.reserve(static_cast<size_t>(n));
    const double r2 = radius * radius;
    const bool sphere = crop == CropKind::sphere;
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d p = pts.row(i).cast<double>().transpose();
        if (sphere ? (p - centre).squaredNorm() < r2 : std::abs(p.z() - centre.z()) < radius)
            kept.push_back(i);
    }
    return kept;
}

Points crop_points(CropKind crop, const Points& pts, const Eigen::Vector3d& centre,
                   double radius) {
    const std::vector<int> keep = crop_indices(crop, pts, centre, radius);
    Points out(int64_t(keep.size()), 3);
    for (size_t i = 0; i < keep.size(); ++i) out.row(int64_t(i)) = pts.row(keep[i]);
    return out;
}

double box_iou(double ax, double ay, double aw, double ah, double bx, double by, double bw,
               double bh) {
    const double x0 = std::max(ax, bx), y0 = std::max(ay, by);
    const double x1 = std::min(ax + aw, bx + bw), y1 = std::min(ay + ah, by + bh);
    const double inter = std::max(0.0, x1 - x0) * std::max(0.0, y1 - y0);
    const double uni = aw * ah + bw * bh - inter;
    return uni > 0 ? inter / uni : 0.0;
}

Box2i clip_box(const Box2i& b, int width, int height) {
    const int64_t x0 = std::max<int64_t>(0, b.x), y0 = std::max<int64_t>(0, b.y);
    const int64_t x1 = std::min<int64_t>(width, int64_t(b.x) + std::max(0, b.w));
    const int64_t y1 = std::min<int64_t>(height, int64_t(b.y) + std::max(0, b.h));
    if (x1 <= x0 || y1 <= y0) return {};
    return {int(x0), int(y0), int(x1 - x0), int(y1 - y0)};
}

namespace {
void check_depth_and_camera(const char* op, const float* depth, int w, int h, const Intrinsics& K) {
    G2L_CHECK(depth != nullptr && w > 0 && h > 0, op, ": no depth image (", w, " x ", h, ")");
    G2L_CHECK(std::isfinite(K.fx) && std::isfinite(K.fy) && K.fx > 0 && K.fy > 0 &&
                  std::isfinite(K.cx) && std::isfinite(K.cy),
              op, ": intrinsics fx ", K.fx, ", fy ", K.fy, ", cx ", K.cx, ", cy ", K.cy,
              " (focal lengths must be finite and > 0)");
}
}  // namespace

bool box_centre(const float* depth, int w, int h, const Intrinsics& K, const Box2i& box_in,
                Eigen::Vector3d* centre) {
    check_depth_and_camera("box_centre", depth, w, h, K);
    const Box2i box = clip_box(box_in, w, h);
    if (box.empty()) return false;
    auto valid = [](float z) { return z > 0 && std::isfinite(z); };
    std::vector<float> zs;
    for (int pass = 0; pass < 2; ++pass) {
        const int x0 = pass ? box.x : box.x + box.w / 3, y0 = pass ? box.y : box.y + box.h / 3;
        const int x1 = pass ? box.x + box.w : box.x + box.w - box.w / 3;
        const int y1 = pass ? box.y + box.h : box.y + box.h - box.h / 3;
        zs.clear();
        for (int v = y0; v < y1; ++v)
            for (int u = x0; u < x1; ++u)
                if (valid(depth[size_t(v) * size_t(w) + size_t(u)]))
                    zs.push_back(depth[size_t(v) * size_t(w) + size_t(u)]);
        if (zs.empty()) continue;
        std::nth_element(zs.begin(), zs.begin() + long(zs.size() / 2), zs.end());
        const float zm = zs[zs.size() / 2];
        const double cu = box.x + box.w / 2.0, cv = box.y + box.h / 2.0;
        double best_dz = 1e30, best_d2 = 1e30;
        int bu = -1, bv = -1;
        for (int v = y0; v < y1; ++v)
            for (int u = x0; u < x1; ++u) {
                const float z = depth[size_t(v) * size_t(w) + size_t(u)];
                if (!valid(z)) continue;
                const double dz = std::fabs(z - zm), d2 = (u - cu) * (u - cu) + (v - cv) * (v - cv);
                if (dz < best_dz || (dz == best_dz && d2 < best_d2))
                    best_dz = dz, best_d2 = d2, bu = u, bv = v;
            }
        const double z = depth[size_t(bv) * size_t(w) + size_t(bu)];
        *centre = {(bu - K.cx) * z / K.fx, (bv - K.cy) * z / K.fy, z};
        return true;
    }
    return false;
}

bool peak_centre(const float* depth, int w, int h, const Intrinsics& K, const Box2i& box_in,
                 double u, double v, Eigen::Vector3d* centre) {
    check_depth_and_camera("peak_centre", depth, w, h, K);
    const Box2i box = clip_box(box_in, w, h);
    if (box.empty() || !std::isfinite(u) || !std::isfinite(v)) return false;
    auto valid = [](float z) { return z > 0 && std::isfinite(z); };
    const int pu = std::clamp(int(std::floor(u)), box.x, box.x + box.w - 1);
    const int pv = std::clamp(int(std::floor(v)), box.y, box.y + box.h - 1);
    const int rmax = std::max(box.w, box.h);
    for (int r = 0; r <= rmax; ++r) {
        double best = 1e30;
        float bz = 0;
        for (int y = pv - r; y <= pv + r; ++y) {
            if (y < box.y || y >= box.y + box.h) continue;
            for (int x = pu - r; x <= pu + r; ++x) {
                if (x < box.x || x >= box.x + box.w) continue;
                if (std::max(std::abs(x - pu), std::abs(y - pv)) != r) continue;  // the ring only
                const float z = depth[size_t(y) * size_t(w) + size_t(x)];
                const double d2 = double(x - pu) * (x - pu) + double(y - pv) * (y - pv);
                if (valid(z) && d2 < best) best = d2, bz = z;
            }
        }
        if (best < 1e30) {
            *centre = {(u - K.cx) * bz / K.fx, (v - K.cy) * bz / K.fy, double(bz)};
            return true;
        }
    }
    return false;
}

}  // namespace g2l::geom
