// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <fstream>

#include "data/detections.h"
#include "testing.h"

using Catch::Matchers::Contains;
using g2l::data::parse_bop_detections;

TEST_CASE("BOP detection files: fields, defaults and aliases", "[data]") {
    const auto d = parse_bop_detections(
        R"([{"scene_id": 48, "image_id": 1, "category_id": 5, "bbox": [10.5, 20, 30, 40.25],
             "score": 0.75, "time": 0.031, "segmentation": {"counts": "x", "size": [4, 4]}},
            {"obj_id": 2, "im_id": 7, "bbox": [0, 0, 0, 0]}])",
        "mem");
    REQUIRE(d.size() == 2);
    CHECK(d[0].scene_id == 48);
    CHECK(d[0].image_id == 1);
    CHECK(d[0].obj_id == 5);
    CHECK(d[0].x == 10.5);
    CHECK(d[0].h == 40.25);
    CHECK(d[0].score == 0.75);
    CHECK(d[0].time == 0.031);
    CHECK(d[1].obj_id == 2);
    CHECK(d[1].image_id == 7);
    CHECK(d[1].scene_id == -1);
    CHECK(d[1].score == 1.0);
    CHECK(d[1].time == -1.0);
    CHECK(parse_bop_detections("[]", "mem").empty());
    CHECK(d[0].peak_x == -1.0);  // no peak: the sphere centre comes from the box
    const auto p = parse_bop_detections(R"([{"obj_id": 2, "bbox": [0, 0, 9, 9], "peak": [4.5, 3]}])",
                                        "mem");
    CHECK(p.at(0).peak_x == 4.5);
    CHECK(p.at(0).peak_y == 3.0);
}

TEST_CASE("BOP detection files: malformed input names the file, entry and key", "[data]") {
    auto bad = [](const std::string& text, const std::string& what) {
        INFO(text);
        REQUIRE_THROWS_WITH(parse_bop_detections(text, "dets.json"),
                            Contains("dets.json") && Contains(what));
    };
    bad("{", "invalid JSON at byte");
    bad(R"({"category_id": 1})", "expected a JSON array");
    bad("[1]", "'[0]' must be a JSON object, got 1");
    bad(R"([{"bbox": [1, 2, 3, 4]}])", "exactly one of 'category_id' and 'obj_id'");
    bad(R"([{"category_id": 1, "obj_id": 1, "bbox": [1, 2, 3, 4]}])", "exactly one of");
    bad(R"([{"category_id": 1}])", "'[0].bbox' is required");
    bad(R"([{"category_id": 1, "bbox": [1, 2, 3]}])", "'[0].bbox' must be an array of 4 numbers, got [1,2,3]");
    bad(R"([{"category_id": 1, "bbox": [1, 2, 3, "4"]}])", "'[0].bbox[3]' must be a number, got \"4\"");
    bad(R"([{"category_id": 1, "bbox": [1, 2, -3, 4]}])", "width and height must be >= 0");
    bad(R"([{"category_id": 0, "bbox": [1, 2, 3, 4]}])", "'[0].category_id' must be an integer >= 1, got 0");
    bad(R"([{"category_id": 1.5, "bbox": [1, 2, 3, 4]}])", "'[0].category_id' must be an integer in the range of 32 bits, got 1.5");
    bad(R"([{"category_id": 1, "scene_id": -2, "bbox": [1, 2, 3, 4]}])", "'[0].scene_id' must be an integer >= 0, got -2");
    bad(R"([{"category_id": 1, "bbox": [1, 2, 3, 4], "score": "high"}])", "'[0].score' must be a number, got \"high\"");
    bad(R"([{"category_id": 1, "bbox": [1, 2, 3, 4]}, {"category_id": 1, "bbox": [1, 2, 3, 4], "scroe": 1}])",
        "unknown key '[1].scroe'");
    bad(R"([{"category_id": 1, "image_id": 1, "im_id": 1, "bbox": [1, 2, 3, 4]}])", "both 'image_id' and 'im_id'");
    bad(R"([{"category_id": 1, "bbox": [1, 2, 3, 4], "peak": [1]}])", "'[0].peak' must be an array of 2 numbers, got [1]");
    bad(R"([{"category_id": 1, "bbox": [1, 2, 3, 4], "peak": [1, -2]}])", "'[0].peak' must be >= 0, got [1, -2]");
    REQUIRE_THROWS_WITH(g2l::data::load_bop_detections("/nonexistent/dets.json"),
                        Contains("/nonexistent/dets.json") && Contains("cannot open"));
    const std::string dir = g2l::testing::temp_dir("dets");
    std::ofstream(dir + "/d.json") << R"([{"category_id": 3, "bbox": [1, 2, 3, 4]}])";
    CHECK(g2l::data::load_bop_detections(dir + "/d.json").at(0).obj_id == 3);
}

TEST_CASE("BOP results CSV: rows, and every malformed line named", "[data]") {
    using g2l::data::parse_bop_results_csv;
    const auto rows = parse_bop_results_csv(
        "scene_id,im_id,obj_id,score,R,t,time\r\n"
        "48,1,5,0.75,1 0 0 0 1 0 0 0 1,10.5 -2 600,0.031\n"
        "\n"
        "0,7,2,-1,0 -1 0 1 0 0 0 0 1,0 0 1e3,-1\n",
        "mem");
    REQUIRE(rows.size() == 2);
    CHECK(rows[0].scene_id == 48);
    CHECK(rows[0].image_id == 1);
    CHECK(rows[0].obj_id == 5);
    CHECK(rows[0].score == 0.75);
    CHECK(rows[0].R[4] == 1.0);
    CHECK(rows[0].t[0] == 10.5);
    CHECK(rows[0].t[2] == 600.0);
    CHECK(rows[0].time == 0.031);
    CHECK(rows[1].R[1] == -1.0);
    CHECK(rows[1].t[2] == 1000.0);
    CHECK(rows[1].time == -1.0);
    const std::string head = "scene_id,im_id,obj_id,score,R,t,time\n";
    CHECK_THROWS_WITH(parse_bop_results_csv("", "e.csv"), Contains("no BOP header"));
    CHECK_THROWS_WITH(parse_bop_results_csv("scene,im,obj\n", "h.csv"),
                      Contains("the first line must be the BOP header"));
    CHECK_THROWS_WITH(parse_bop_results_csv(head + "1,2,3\n", "f.csv"),
                      Contains("'f.csv' line 2: expected 7 comma-separated fields"));
    CHECK_THROWS_WITH(parse_bop_results_csv(head + "1,2,0,1,1 0 0 0 1 0 0 0 1,0 0 1,0\n", "o.csv"),
                      Contains("obj_id '0' is not an integer >= 1"));
    CHECK_THROWS_WITH(parse_bop_results_csv(head + "1.5,2,3,1,1 0 0 0 1 0 0 0 1,0 0 1,0\n", "s.csv"),
                      Contains("scene_id '1.5'"));
    CHECK_THROWS_WITH(parse_bop_results_csv(head + "1,2,3,nan,1 0 0 0 1 0 0 0 1,0 0 1,0\n", "n.csv"),
                      Contains("score 'nan' is not a list of finite numbers"));
    CHECK_THROWS_WITH(parse_bop_results_csv(head + "1,2,3,1,1 0 0 0 1 0 0 0 1,0 0,0\n", "t.csv"),
                      Contains("R needs 9 numbers and t 3, got 9 and 2"));
    CHECK_THROWS_WITH(parse_bop_results_csv(head + "1,2,3,1,1 0 0 0 x 0 0 0 1,0 0 1,0\n", "r.csv"),
                      Contains("line 2: R '1 0 0 0 x 0 0 0 1'"));
    CHECK_THROWS_WITH(g2l::data::load_bop_results_csv("/nonexistent/r.csv"),
                      Contains("'/nonexistent/r.csv': cannot open"));
}
