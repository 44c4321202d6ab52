// SPDX-License-Identifier: MIT
#include "data/draw.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

#include <opencv2/imgproc.hpp>

namespace g2l::data {

namespace {

void put(Image* im, int u, int v, const Rgb& c) {
    if (u < 0 || v < 0 || u >= im->w || v >= im->h) return;
    uint8_t* p = &im->data[(size_t(v) * size_t(im->w) + size_t(u)) * 3];
    p[0] = c[0], p[1] = c[1], p[2] = c[2];
}

}  // namespace

void draw_line(Image* im, double u0, double v0, double u1, double v1, const Rgb& color,
               int thickness) {
    G2L_CHECK(im && im->channels == 3 && im->w > 0 && im->h > 0 &&
                  im->data.size() == size_t(im->w) * size_t(im->h) * 3,
              "draw_line: expected a w x h x 3 image");
    // A non-finite end (e.g. a projection of a point on the camera plane) draws nothing.
    if (!std::isfinite(u0) || !std::isfinite(v0) || !std::isfinite(u1) || !std::isfinite(v1))
        return;
    // Clip to a generous window first so a far-away end point cannot make the loop huge.
    const double lim = 4.0 * std::max(im->w, im->h);
    if (std::fabs(u0) > lim || std::fabs(u1) > lim || std::fabs(v0) > lim || std::fabs(v1) > lim) {
        const double s = lim / std::max({std::fabs(u0), std::fabs(u1), std::fabs(v0), std::fabs(v1)});
        if (std::fabs(u1) > lim || std::fabs(v1) > lim) {
            u1 = u0 + (u1 - u0) * s, v1 = v0 + (v1 - v0) * s;
        } else {
            u0 = u1 + (u0 - u1) * s, v0 = v1 + (v0 - v1) * s;
        }
        if (std::fabs(u0) > lim || std::fabs(v0) > lim || std::fabs(u1) > lim || std::fabs(v1) > lim) return;
    }
    // At least one step per pixel along the longer axis, so the line has no gaps.
    const int steps = int(std::ceil(std::max(std::fabs(u1 - u0), std::fabs(v1 - v0)))) + 1;
    const int r = std::max(0, thickness - 1) / 2;
    for (int i = 0; i <= steps; ++i) {
        const double a = double(i) / steps;
        const int u = int(std::lround(u0 + a * (u1 - u0))), v = int(std::lround(v0 + a * (v1 - v0)));
        // An even thickness gets its extra row / column on the + side: exactly `thickness` wide.
        for (int dv = -r; dv <= r + (thickness % 2 == 0 ? 1 : 0); ++dv)
            for (int du = -r; du <= r + (thickness % 2 == 0 ? 1 : 0); ++du) put(im, u + du, v + dv, color);
    }
}

void draw_box3d(Image* im, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                const geom::Pose& pose, const geom::Intrinsics& K, const Rgb& color,
                int thickness) {
    std::array<Eigen::Vector3d, 8> c;
    for (int i = 0; i < 8; ++i) {
        // Corner i: bit 0 picks x, bit 1 y, bit 2 z; an edge joins corners that differ in one bit.
        const Eigen::Vector3d m(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
        c[size_t(i)] = pose.R * m + pose.t;
    }
    for (int i = 0; i < 8; ++i)
        for (int bit = 1; bit < 8; bit <<= 1) {
            // j > i only (j == i is skipped), so each of the 12 edges is drawn once.
            const int j = i | bit;
            if (j == i) continue;
            const Eigen::Vector3d& a = c[size_t(i)];
            const Eigen::Vector3d& b = c[size_t(j)];
            // An end at or behind the camera plane would project mirrored: skip the edge.
            if (!(a.z() > 0) || !(b.z() > 0)) continue;
            draw_line(im, K.fx * a.x() / a.z() + K.cx, K.fy * a.y() / a.z() + K.cy,
                      K.fx * b.x() / b.z() + K.cx, K.fy * b.y() / b.z() + K.cy, color, thickness);
        }
}

Image depth_to_rgb(const std::vector<float>& depth, int w, int h) {
    G2L_CHECK(w > 0 && h > 0 && depth.size() == size_t(w) * size_t(h),
              "depth_to_rgb: ", depth.size(), " values for a ", w, " x ", h, " image");
    float lo = 1e30f, hi = 0;
    for (float z : depth)
        if (z > 0 && std::isfinite(z)) lo = std::min(lo, z), hi = std::max(hi, z);
    Image im{w, h, 3, std::vector<uint8_t>(size_t(w) * size_t(h) * 3, 0)};
    if (hi <= 0) return im;
    // At least 1 mm, so a flat depth image does not divide by zero.
    const float span = std::max(1.f, hi - lo);
    for (size_t i = 0; i < depth.size(); ++i) {
        const float z = depth[i];
        if (!(z > 0) || !std::isfinite(z)) continue;
        // Near is bright; the range starts at 60 so the farthest surface stays distinct from the
        // black of pixels without depth.
        const uint8_t g = uint8_t(60 + 195 * (1 - (z - lo) / span));
        im.data[i * 3] = im.data[i * 3 + 1] = im.data[i * 3 + 2] = g;
    }
    return im;
}

Image plot_curves(const std::vector<std::vector<std::pair<double, double>>>& curves,
                  const std::vector<Rgb>& colors, double x_max, int w, int h) {
    G2L_CHECK(w >= 64 && h >= 64 && std::isfinite(x_max) && x_max > 0,
              "plot_curves: bad size ", w, " x ", h, " or x_max ", x_max);
    G2L_CHECK(colors.size() >= curves.size(), "plot_curves: ", curves.size(), " curves but ",
              colors.size(), " colours");
    Image im{w, h, 3, std::vector<uint8_t>(size_t(w) * size_t(h) * 3, 255)};
    const int m = 32;  // margin
    auto X = [&](double x) { return m + (w - 2 * m) * std::clamp(x / x_max, 0.0, 1.0); };
    // y is a percentage (accuracy curves), plotted on a fixed 0-100 axis.
    auto Y = [&](double y) { return h - m - (h - 2 * m) * std::clamp(y / 100.0, 0.0, 1.0); };
    const Rgb grid{220, 220, 220}, axis{0, 0, 0};
    for (int k = 1; k <= 4; ++k) {
        draw_line(&im, X(0), Y(25.0 * k), X(x_max), Y(25.0 * k), grid);
        draw_line(&im, X(x_max * k / 4), Y(0), X(x_max * k / 4), Y(100), grid);
    }
    draw_line(&im, X(0), Y(0), X(x_max), Y(0), axis);
    draw_line(&im, X(0), Y(0), X(0), Y(100), axis);
    for (size_t c = 0; c < curves.size(); ++c)
        for (size_t i = 1; i < curves[c].size(); ++i)
            draw_line(&im, X(curves[c][i - 1].first), Y(curves[c][i - 1].second),
                      X(curves[c][i].first), Y(curves[c][i].second), colors[c], 2);
    return im;
}

void draw_rect(Image* image, double x, double y, double w, double h, const Rgb& color,
               int thickness) {
    draw_line(image, x, y, x + w, y, color, thickness);
    draw_line(image, x + w, y, x + w, y + h, color, thickness);
    draw_line(image, x + w, y + h, x, y + h, color, thickness);
    draw_line(image, x, y + h, x, y, color, thickness);
}

void draw_text(Image* image, int x, int y, const std::string& text, const Rgb& color,
               double scale) {
    G2L_CHECK(image && image->channels == 3 && image->w > 0 && image->h > 0 &&
                  image->data.size() == size_t(image->w) * size_t(image->h) * 3,
              "draw_text: need a 3-channel image of matching size");
    G2L_CHECK(std::isfinite(scale) && scale > 0, "draw_text: scale must be > 0, got ", scale);
    cv::Mat m(image->h, image->w, CV_8UC3, image->data.data());
    int base = 0;
    const cv::Size sz = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &base);
    // A black box behind the text keeps it readable on any image.
    cv::rectangle(m, cv::Point(x - 1, y - sz.height - 2), cv::Point(x + sz.width + 1, y + base),
                  cv::Scalar(0, 0, 0), cv::FILLED);
    // The image is RGB; OpenCV only writes the three bytes in the order given.
    cv::putText(m, text, cv::Point(x, y), cv::FONT_HERSHEY_SIMPLEX, scale,
                cv::Scalar(color[0], color[1], color[2]), 1, cv::LINE_AA);
}

}  // namespace g2l::data
