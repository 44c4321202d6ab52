// SPDX-License-Identifier: MIT
// Drawing for the pictures (data/draw.h): lines, boxes and labels land where asked, clipped to
// the image, and a wrong image is refused.
#include <catch2/catch.hpp>
#include <algorithm>

#include "core/error.h"
#include "data/draw.h"

using namespace g2l;
using namespace g2l::data;
using Catch::Contains;

namespace {
Image blank(int w, int h) { return Image{w, h, 3, std::vector<uint8_t>(size_t(w * h * 3), 0)}; }
int lit(const Image& im, int x0, int y0, int x1, int y1) {  // pixels not black in the rectangle
    int n = 0;
    for (int y = std::max(0, y0); y < std::min(im.h, y1); ++y)
        for (int x = std::max(0, x0); x < std::min(im.w, x1); ++x)
            n += im.at(x, y, 0) || im.at(x, y, 1) || im.at(x, y, 2);
    return n;
}
}  // namespace

TEST_CASE("draw_rect and draw_text: where asked, clipped, bad images refused", "[data]") {
    Image im = blank(120, 80);
    draw_rect(&im, 10, 10, 40, 30, {250, 210, 0});
    CHECK(im.at(10, 10, 0) == 250);
    CHECK(im.at(50, 40, 1) == 210);
    CHECK(lit(im, 12, 12, 48, 38) == 0);  // an outline: the inside stays empty
    CHECK(lit(im, 0, 0, 120, 80) >= 2 * (40 + 30));
    // Text: pixels in the colour asked near its baseline, nothing far from it.
    Image t = blank(120, 80);
    draw_text(&t, 5, 30, "8 0.73", {120, 170, 255});
    CHECK(lit(t, 0, 15, 60, 34) > 20);
    CHECK(lit(t, 0, 45, 120, 80) == 0);
    bool coloured = false;
    for (int y = 15; y < 34; ++y)
        for (int x = 0; x < 60; ++x) coloured = coloured || (t.at(x, y, 2) > 200 && t.at(x, y, 0) > 80);
    CHECK(coloured);
    // Off the image: clipped, no crash.
    draw_text(&t, 110, 5, "overlap 0.18", {255, 120, 120});
    draw_text(&t, -50, 200, "x", {255, 255, 255});
    draw_rect(&t, -10, -10, 500, 500, {255, 255, 255});
    Image bad{10, 10, 1, std::vector<uint8_t>(100, 0)};
    CHECK_THROWS_WITH(draw_text(&bad, 0, 5, "a", {255, 255, 255}), Contains("3-channel"));
    CHECK_THROWS_WITH(draw_text(&im, 0, 5, "a", {255, 255, 255}, 0.0), Contains("scale"));
}
