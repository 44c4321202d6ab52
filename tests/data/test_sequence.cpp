// SPDX-License-Identifier: MIT
// The frames of a video: a BOP scene folder and a list file (data/sequence.h).
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>

#include "data/sequence.h"
#include "testing.h"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {
void touch(const fs::path& p, const std::string& text = "x") {
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
}
}  // namespace

TEST_CASE("list_bop_scene: frames by id, their images and cameras, bad folders named", "[data]") {
    const fs::path d = g2l::testing::temp_dir("sequence");
    const std::string K = R"({"cam_K": [500, 0, 320, 0, 500, 240, 0, 0, 1], "depth_scale": 0.1})";
    touch(d / "scene_camera.json", "{\"2\": " + K + ", \"10\": " + K + ", \"11\": {\"cam_K\": [1]}}");
    for (const char* n : {"10", "2", "11", "12"}) touch(d / "depth" / (std::string("0000") + (n[1] ? "" : "0") + n + ".png"));
    touch(d / "depth" / "notes.txt");
    touch(d / "rgb" / "000002.png");
    touch(d / "rgb" / "000010.jpg");
    const auto frames = g2l::data::list_bop_scene(d.string());
    REQUIRE(frames.size() == 4);
    CHECK(frames[0].image_id == 2);  // numeric order, not the listing's
    CHECK(frames[1].image_id == 10);
    CHECK(frames[2].image_id == 11);
    CHECK(frames[3].image_id == 12);
    CHECK(frames[0].rgb == (d / "rgb" / "000002.png").string());
    CHECK(frames[1].rgb == (d / "rgb" / "000010.jpg").string());
    CHECK(frames[2].rgb.empty());
    CHECK(frames[0].camera_error.empty());
    CHECK(frames[0].camera.fx == 500);
    CHECK(frames[0].camera.depth_scale == 0.1);
    // A bad or missing camera entry is that frame's error, not the scene's.
    CHECK_THAT(frames[2].camera_error, Contains("'11.cam_K'"));
    CHECK_THAT(frames[3].camera_error, Contains("no entry for image 12"));

    CHECK_THROWS_WITH(g2l::data::list_bop_scene((d / "none").string()), Contains("is not a folder"));
    const fs::path e = g2l::testing::temp_dir("sequence_empty");
    fs::create_directories(e);
    CHECK_THROWS_WITH(g2l::data::list_bop_scene(e.string()), Contains("has no depth/ folder"));
    fs::create_directories(e / "depth");
    CHECK_THROWS_WITH(g2l::data::list_bop_scene(e.string()), Contains("has no scene_camera.json"));
    touch(e / "scene_camera.json", "{\"1\": ");
    CHECK_THROWS_WITH(g2l::data::list_bop_scene(e.string()), Contains("scene_camera.json"));
    touch(e / "scene_camera.json", "{}");
    CHECK_THROWS_WITH(g2l::data::list_bop_scene(e.string()), Contains("no depth image"));
    touch(e / "depth" / "frame_a.png");
    CHECK_THROWS_WITH(g2l::data::list_bop_scene(e.string()),
                      Contains("depth file 'frame_a.png' is not named by its image id"));
}

TEST_CASE("list_frames_file: paths relative to the list, one camera, bad lines named", "[data]") {
    const fs::path d = g2l::testing::temp_dir("frame_list");
    g2l::data::CameraFile cam;
    cam.fx = cam.fy = 500, cam.depth_scale = 1;
    touch(d / "list.txt", "# depth rgb\n a/d1.png a/c1.png \n\n/abs/d2.png # a comment\n");
    const auto frames = g2l::data::list_frames_file((d / "list.txt").string(), cam);
    REQUIRE(frames.size() == 2);
    CHECK(frames[0].image_id == 1);
    CHECK(frames[0].depth == (d / "a/d1.png").string());
    CHECK(frames[0].rgb == (d / "a/c1.png").string());
    CHECK(frames[1].image_id == 2);
    CHECK(frames[1].depth == "/abs/d2.png");
    CHECK(frames[1].rgb.empty());
    CHECK(frames[1].camera.fx == 500);
    touch(d / "bad.txt", "d1.png c1.png x.png\n");
    CHECK_THROWS_WITH(g2l::data::list_frames_file((d / "bad.txt").string(), cam),
                      Contains("bad.txt' line 1: expected DEPTH_PNG [RGB_IMAGE], got a third path 'x.png'"));
    touch(d / "empty.txt", "# nothing\n");
    CHECK_THROWS_WITH(g2l::data::list_frames_file((d / "empty.txt").string(), cam), Contains("lists no frame"));
    CHECK_THROWS_WITH(g2l::data::list_frames_file((d / "none.txt").string(), cam), Contains("cannot be opened"));
}
