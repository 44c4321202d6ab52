// SPDX-License-Identifier: MIT
#include "geometry/camera.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace g2l::geom {
namespace {

void check_image_args(const void* depth, int width, int height, const Intrinsics& K,
                      const char* fn) {
    G2L_CHECK(depth != nullptr, fn, ": depth pointer is null");
    G2L_CHECK(width > 0 && height > 0, fn, ": image size must be positive, got ", width, " x ",
              height);
    G2L_CHECK(std::isfinite(K.fx) && std::isfinite(K.fy) && K.fx > 0 && K.fy > 0, fn,
              ": focal lengths must be finite and > 0, got fx=", K.fx, " fy=", K.fy);
    G2L_CHECK(std::isfinite(K.cx) && std::isfinite(K.cy), fn,
              ": principal point must be finite, got cx=", K.cx, " cy=", K.cy);
    G2L_CHECK((K.width == 0 || K.width == width) && (K.height == 0 || K.height == height), fn,
              ": intrinsics are for a ", K.width, " x ", K.height, " image but the depth image is ",
              width, " x ", height);
}

/// Shared back-projection loop; `depth_at(i)` returns the depth in mm of flat pixel i, or a value
/// <= 0 / non-finite for "no measurement".
template <class DepthAt>
Points back_project(DepthAt depth_at, int width, int height, const Intrinsics& K,
                    const Box2i& box, std::vector<int>* pixel_index) {
    // Clip [x, x + w) x [y, y + h) to the image; 64-bit sums so huge boxes cannot overflow.
    const int u0 = static_cast<int>(std::max<int64_t>(box.x, 0));
    const int v0 = static_cast<int>(std::max<int64_t>(box.y, 0));
    const int u1 = static_cast<int>(std::min<int64_t>(int64_t(box.x) + box.w, width));
    const int v1 = static_cast<int>(std::min<int64_t>(int64_t(box.y) + box.h, height));
    std::vector<float> xyz;
    if (pixel_index) pixel_index->clear();
    if (u1 > u0 && v1 > v0) xyz.reserve(size_t(u1 - u0) * size_t(v1 - v0) * 3);
    const double inv_fx = 1.0 / K.fx, inv_fy = 1.0 / K.fy;
    for (int v = v0; v < v1; ++v) {
        for (int u = u0; u < u1; ++u) {
            const int i = v * width + u;
            const double z = depth_at(i);
            if (!(z > 0) || !std::isfinite(z)) continue;
            xyz.push_back(static_cast<float>((u - K.cx) * z * inv_fx));
            xyz.push_back(static_cast<float>((v - K.cy) * z * inv_fy));
            xyz.push_back(static_cast<float>(z));
            if (pixel_index) pixel_index->push_back(i);
        }
    }
    const Eigen::Index n = static_cast<Eigen::Index>(xyz.size() / 3);
    return Eigen::Map<const Points>(xyz.data(), n, 3);
}

}  // namespace

Points depth_to_points(const uint16_t* depth, int width, int height, double depth_scale,
                       const Intrinsics& K, const Box2i& box, std::vector<int>* pixel_index) {
    check_image_args(depth, width, height, K, "depth_to_points(uint16)");
    G2L_CHECK(std::isfinite(depth_scale) && depth_scale > 0,
              "depth_to_points: depth_scale must be finite and > 0, got ", depth_scale);
    return back_project([&](int i) { return depth[i] * depth_scale; }, width, height, K, box,
                        pixel_index);
}

Points depth_to_points(const float* depth_mm, int width, int height, const Intrinsics& K,
                       const Box2i& box, std::vector<int>* pixel_index) {
    check_image_args(depth_mm, width, height, K, "depth_to_points(float)");
    return back_project([&](int i) { return double(depth_mm[i]); }, width, height, K, box,
                        pixel_index);
}

Pixels project(const Points& pts, const Intrinsics& K) {
    G2L_CHECK(std::isfinite(K.fx) && std::isfinite(K.fy) && K.fx > 0 && K.fy > 0,
              "project: focal lengths must be finite and > 0, got fx=", K.fx, " fy=", K.fy);
    Pixels uv(pts.rows(), 2);
    for (Eigen::Index i = 0; i < pts.rows(); ++i) {
        const double x = pts(i, 0), y = pts(i, 1), z = pts(i, 2);
        G2L_CHECK(std::isfinite(x) && std::isfinite(y) && std::isfinite(z),
                  "project: point ", i, " is not finite: (", x, ", ", y, ", ", z, ")");
        G2L_CHECK(z > 0, "project: point ", i, " has Z = ", z, " mm (must be in front, > 0)");
        uv(i, 0) = static_cast<float>(K.fx * x / z + K.cx);
        uv(i, 1) = static_cast<float>(K.fy * y / z + K.cy);
    }
    return uv;
}

Intrinsics intrinsics_from_cam_K(const double K[9], int width, int height) {
    G2L_CHECK(K != nullptr, "intrinsics_from_cam_K: cam_K pointer is null");
    for (int i = 0; i < 9; ++i) {
        G2L_CHECK(std::isfinite(K[i]), "intrinsics_from_cam_K: cam_K[", i, "] is not finite (",
                  K[i], ")");
    }
    G2L_CHECK(width > 0 && height > 0, "intrinsics_from_cam_K: image size must be positive, got ",
              width, " x ", height);
    G2L_CHECK(K[0] > 0 && K[4] > 0, "intrinsics_from_cam_K: fx=cam_K[0] and fy=cam_K[4] must be "
              "> 0, got fx=", K[0], " fy=", K[4]);
    // Zero skew and a (0, 0, 1) last row: anything else is not a pinhole K we can represent.
    G2L_CHECK(std::abs(K[1]) <= 1e-9 * K[0] && K[3] == 0,
              "intrinsics_from_cam_K: cam_K has skew / off-diagonal terms cam_K[1]=", K[1],
              " cam_K[3]=", K[3], " (expected 0)");
    G2L_CHECK(K[6] == 0 && K[7] == 0 && std::abs(K[8] - 1) < 1e-9,
              "intrinsics_from_cam_K: last row of cam_K must be (0, 0, 1), got (", K[6], ", ",
              K[7], ", ", K[8], ")");
    Intrinsics in;
    in.fx = K[0];
    in.fy = K[4];
    in.cx = K[2];
    in.cy = K[5];
    in.width = width;
    in.height = height;
    return in;
}

std::string implausible_camera(const Intrinsics& K, int width, int height) {
    if (width <= 0 || height <= 0) return cat("the image is ", width, " x ", height, " pixels");
    const double fov = 2 * std::atan(0.5 * width / K.fx) * 180 / M_PI;
    if (!(fov >= 20 && fov <= 140))
        return cat("fx = ", K.fx, " gives a ", int(std::lround(fov)), " degree field of view on a ",
                   width, " pixel wide image (RGB-D cameras: 20-140)");
    if (std::abs(K.fx / K.fy - 1) > 0.1)
        return cat("fx = ", K.fx, " and fy = ", K.fy, " differ by more than 10 %");
    if (K.cx < 0.2 * width || K.cx > 0.8 * width || K.cy < 0.2 * height || K.cy > 0.8 * height)
        return cat("the principal point (", K.cx, ", ", K.cy, ") is off the middle of the ", width,
                   " x ", height, " image (intrinsics of another resolution?)");
    return "";
}

}  // namespace g2l::geom
