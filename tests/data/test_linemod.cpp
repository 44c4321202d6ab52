// SPDX-License-Identifier: MIT
// Linemod_preprocessed reader and its YAML-subset parser, on a tiny layout written by the test
// (object 01 with 2 frames; frame 0 also annotates object 05, as data/02 does in the release).
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "data/linemod_preprocessed.h"
#include "data/simple_yaml.h"
#include "geometry/mesh_io.h"
#include "testing.h"

namespace fs = std::filesystem;
using Catch::Contains;
using namespace g2l;
using namespace g2l::data;

namespace {

constexpr int kW = 64, kH = 48;

void write_text(const std::string& path, const std::string& text) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    REQUIRE(f.good());
    f << text;
}

const char* kGt =
    "0:\n"
    "- cam_R_m2c: [1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0]\n"
    "  cam_t_m2c: [10.5, -20.25, 800.0]\n"
    "  obj_bb: [30, 20, 10, 12]\n"
    "  obj_id: 1\n"
    "- cam_R_m2c: [0.0, -1.0, 0.0,\n"
    "      1.0, 0.0, 0.0, 0.0, 0.0, 1.0]   # a list continued on the next line\n"
    "  cam_t_m2c: [-100.0, 0.0, 900.0]\n"
    "  obj_bb: [1, 2, 3, 4]\n"
    "  obj_id: 5\n"
    "\n"
    "1:\n"
    "- cam_R_m2c: [0.86602540, -0.50000000, 0.00000000, 0.50000000, 0.86602540, 0.00000000, "
    "0.00000000, 0.00000000, 1.00000000]\n"
    "  cam_t_m2c: [-105.35775150, -117.52119142, 1014.87701320]\n"
    "  obj_bb: [244, 150, 44, 58]\n"
    "  obj_id: 1\n";

const char* kInfo =
    "0:\n"
    "  cam_K: [572.41140000, 0.00000000, 325.26110000, 0.00000000, 573.57043000, 242.04899000, "
    "0.00000000, 0.00000000, 1.00000000]\n"
    "  depth_scale: 1.0\n"
    "1:\n"
    "  cam_K: [572.41140000, 0.00000000, 325.26110000, 0.00000000, 573.57043000, 242.04899000, "
    "0.00000000, 0.00000000, 1.00000000]\n"
    "  depth_scale: 0.5\n";

const char* kModelsInfo =
    "1: {diameter: 86.60254038, min_x: -25.0, min_y: -25.0, min_z: -25.0, size_x: 50.0, "
    "size_y: 50.0, size_z: 50.0}\n"
    "5: {diameter: 86.60254038, min_x: -25.0, min_y: -25.0, min_z: -25.0, size_x: 50.0, "
    "size_y: 50.0, size_z: 50.0}\n";

std::vector<uint16_t> depth_of(int image) {
    std::vector<uint16_t> d(kW * kH);
    for (int i = 0; i < kW * kH; ++i) d[i] = static_cast<uint16_t>(700 + 3 * i + image);
    return d;
}

// The corners of the 50 mm cube models_info.yml describes (diameter 86.6 mm: meshes are
// checked against their declared diameter when loaded), four of them joined by faces.
void write_mesh(const std::string& path) {
    geom::Mesh m;
    m.vertices.resize(8, 3);
    m.vertices << -25, -25, -25, 25, -25, -25, 0, 25, -25, 0, 0, 25, 25, 25, 25, -25, 25, 25,
        -25, -25, 25, 25, 25, -25;
    m.faces.resize(4, 3);
    m.faces << 0, 1, 2, 0, 1, 3, 1, 2, 3, 2, 0, 3;
    geom::save_ply(path, m);
}

// Writes the layout and returns its root.
std::string make_layout(const std::string& tag) {
    const std::string root = g2l::testing::temp_dir(tag) + "/Linemod_preprocessed";
    const std::string d = root + "/data/01";
    for (const char* sub : {"/rgb", "/depth", "/mask"}) fs::create_directories(d + sub);
    fs::create_directories(root + "/models");
    for (int i = 0; i < 2; ++i) {
        char stem[16];
        std::snprintf(stem, sizeof(stem), "%04d", i);
        Image rgb{kW, kH, 3, std::vector<uint8_t>(kW * kH * 3, static_cast<uint8_t>(40 + i))};
        save_png(d + "/rgb/" + stem + ".png", rgb);
        // The release's masks are 3-channel 0/255 images.
        Image mask{kW, kH, 3, std::vector<uint8_t>(kW * kH * 3, 0)};
        for (int c = 0; c < 3; ++c) mask.data[(5 * kW + 7) * 3 + c] = 255;
        save_png(d + "/mask/" + stem + ".png", mask);
        const std::vector<uint16_t> depth = depth_of(i);
        save_depth_png(d + "/depth/" + stem + ".png", depth.data(), kW, kH);
    }
    write_text(d + "/gt.yml", kGt);
    write_text(d + "/info.yml", kInfo);
    write_text(d + "/train.txt", "0000\n");
    write_text(d + "/test.txt", "0001\n\n");
    write_text(root + "/models/models_info.yml", kModelsInfo);
    write_mesh(root + "/models/obj_01.ply");
    write_mesh(root + "/models/obj_05.ply");
    return root;
}

}  // namespace

TEST_CASE("Linemod_preprocessed test split: frame, pose, camera, model", "[data]") {
    const std::string root = make_layout("lm_test");
    const LinemodDataset ds = open_linemod_preprocessed(root);
    CHECK(ds.split() == "test");
    REQUIRE(ds.frames().size() == 1);
    const Frame& f = ds.frames()[0];
    CHECK(f.scene == "01");
    CHECK(f.image_id == 1);
    CHECK(f.K.fx == 572.4114);
    CHECK(f.K.fy == 573.57043);
    CHECK(f.K.cx == 325.2611);
    CHECK(f.K.cy == 242.04899);
    CHECK(f.K.width == kW);
    CHECK(f.K.height == kH);
    CHECK(f.depth_scale == 0.5);
    REQUIRE(f.instances.size() == 1);
    const Instance& in = f.instances[0];
    CHECK(in.obj_id == 1);
    CHECK(in.index_in_frame == 0);
    CHECK(in.pose.R(0, 0) == 0.8660254);
    CHECK(in.pose.R(0, 1) == -0.5);  // row-major: second number is R(0, 1)
    CHECK(in.pose.R(1, 0) == 0.5);
    CHECK(in.pose.R(2, 2) == 1.0);
    CHECK(in.pose.t.x() == -105.3577515);
    CHECK(in.pose.t.z() == 1014.8770132);
    CHECK((in.bbox_obj.x == 244 && in.bbox_obj.y == 150 && in.bbox_obj.w == 44 &&
           in.bbox_obj.h == 58));
    CHECK(in.bbox_visib.empty());
    CHECK(in.visib_fract == -1);
    CHECK(fs::path(in.mask_visib_path).filename() == "0001.png");

    int w = 0, h = 0;
    CHECK(ds.load_depth(f, &w, &h) == depth_of(1));
    const Image mask = ds.load_mask(f, in);
    REQUIRE(mask.channels == 1);
    CHECK(mask.at(7, 5) == 255);
    CHECK(mask.at(8, 5) == 0);
    const Image rgb = ds.load_rgb(f);
    CHECK(rgb.at(3, 3, 1) == 41);

    REQUIRE(ds.models().size() == 1);
    const ObjectModel& m = ds.model(1);
    CHECK(m.name == "ape");
    CHECK(m.info.diameter == 86.60254038);
    CHECK(m.info.size.y() == 50.0);
    CHECK_FALSE(m.info.symmetric);
    CHECK(ds.load_model_mesh(1).vertices.rows() == 8);
}

TEST_CASE("Linemod_preprocessed train split keeps other objects on request", "[data]") {
    const std::string root = make_layout("lm_train");
    LinemodOptions o;
    o.split = "train";
    CHECK(open_linemod_preprocessed(root, o).frames()[0].instances.size() == 1);
    o.only_folder_object = false;
    o.symmetric_ids = std::vector<int>{5};
    const LinemodDataset ds = open_linemod_preprocessed(root, o);
    REQUIRE(ds.frames().size() == 1);
    const Frame& f = ds.frames()[0];
    CHECK(f.image_id == 0);
    CHECK(f.depth_scale == 1.0);
    REQUIRE(f.instances.size() == 2);
    CHECK(f.instances[1].obj_id == 5);
    CHECK(f.instances[1].index_in_frame == 1);
    CHECK(f.instances[1].mask_visib_path.empty());  // masks show the folder's object only
    CHECK(f.instances[1].pose.R(0, 1) == -1.0);     // the list continued over two lines
    CHECK(f.instances[1].pose.R(1, 0) == 1.0);
    REQUIRE(ds.models().size() == 2);
    CHECK(ds.model(5).name == "can");
    CHECK(ds.model(5).info.symmetric);
    CHECK_FALSE(ds.model(1).info.symmetric);

    o = {};
    o.split = "all";
    o.objects = {1};
    const LinemodDataset all = open_linemod_preprocessed(root, o);
    REQUIRE(all.frames().size() == 2);
    CHECK(all.frames()[0].image_id == 0);
    CHECK(all.frames()[1].image_id == 1);
}

TEST_CASE("Linemod_preprocessed errors name the file, line and value", "[data]") {
    const std::string root = make_layout("lm_err");
    const std::string d = root + "/data/01";
    LinemodOptions o;
    SECTION("unknown split") {
        o.split = "val";
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o), Contains("got \"val\""));
    }
    SECTION("missing object folder") {
        o.objects = {3};
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o), Contains("data/03"));
    }
    SECTION("listed image without files") {
        write_text(d + "/test.txt", "0001\n0007\n");
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o), Contains("rgb/0007.png"));
    }
    SECTION("malformed split list") {
        write_text(d + "/test.txt", "0001\nabc\n");
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o),
                            Contains("test.txt:2") && Contains("'abc'"));
    }
    SECTION("no camera for a listed image") {
        write_text(d + "/info.yml", std::string(kInfo).substr(0, std::string(kInfo).find("1:")));
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o),
                            Contains("info.yml: no entry for image 1"));
    }
    SECTION("cam_t_m2c of the wrong length") {
        std::string gt = kGt;
        gt.replace(gt.find("[-105.35775150, "), 16, "[");
        write_text(d + "/gt.yml", gt);
        REQUIRE_THROWS_WITH(
            open_linemod_preprocessed(root, o),
            Contains("gt.yml:14") && Contains("'cam_t_m2c' must have 3") && Contains("got 2"));
    }
    SECTION("missing key") {
        std::string gt = kGt;
        gt.replace(gt.find("  obj_bb: [244"), std::string("  obj_bb: [244, 150, 44, 58]\n").size(),
                   "");
        write_text(d + "/gt.yml", gt);
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o),
                            Contains("gt.yml:13: missing key 'obj_bb'"));
    }
    SECTION("a bad number and a NaN") {
        std::string info = kInfo;
        info.replace(info.find("0.5"), 3, "abc");
        write_text(d + "/info.yml", info);
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o),
                            Contains("info.yml:6") && Contains("'abc' is not a finite number"));
        info.replace(info.find("abc"), 3, "nan");
        write_text(d + "/info.yml", info);
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o),
                            Contains("'nan' is not a finite number"));
    }
    SECTION("a rotation that is not one") {
        std::string gt = kGt;
        gt.replace(gt.find("[0.86602540"), 11, "[2.0");
        write_text(d + "/gt.yml", gt);
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o),
                            Contains("gt.yml:13: cam_R_m2c is not a rotation"));
    }
    SECTION("an annotated object without a model file") {
        fs::remove(root + "/models/obj_05.ply");
        o.split = "train";
        o.only_folder_object = false;
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o), Contains("obj_05.ply"));
    }
    SECTION("an image without the folder's object") {
        std::string gt = kGt;
        gt.replace(gt.find("  obj_id: 1\n", gt.find("1:\n")), 12, "  obj_id: 5\n");
        write_text(d + "/gt.yml", gt);
        REQUIRE_THROWS_WITH(
            open_linemod_preprocessed(root, o),
            Contains("gt.yml:12: image 1 has no instance of the folder's object 1"));
    }
    SECTION("missing models_info.yml") {
        fs::remove(root + "/models/models_info.yml");
        REQUIRE_THROWS_WITH(open_linemod_preprocessed(root, o), Contains("models_info.yml"));
    }
}

TEST_CASE("the YAML subset parser accepts only what it documents", "[data]") {
    const std::string dir = g2l::testing::temp_dir("yaml");
    const std::string p = dir + "/a.yml";
    write_text(p, "# header comment\n3: []\n7:\n  k: [1, 2,\n     3]\n  s: -4.5e1  # note\n");
    const std::map<int, YamlBlock> b = parse_int_keyed_yaml(p);
    REQUIRE(b.size() == 2);
    CHECK(b.at(3).is_list);
    CHECK(b.at(3).records.empty());
    REQUIRE(b.at(7).records.size() == 1);
    const YamlRecord& r = b.at(7).records[0];
    CHECK(yaml_numbers(r, "k", 3, p) == std::vector<double>{1, 2, 3});
    CHECK(yaml_numbers(r, "s", 1, p)[0] == -45.0);
    CHECK(r.fields.at("k").is_list);
    CHECK(r.fields.at("s").line == 6);
    REQUIRE_THROWS_WITH(yaml_numbers(r, "q", 1, p), Contains("a.yml:4: missing key 'q'"));

    const auto bad = [&](const std::string& text, const std::string& msg) {
        write_text(p, text);
        REQUIRE_THROWS_WITH(parse_int_keyed_yaml(p), Contains(msg) && Contains("a.yml"));
    };
    bad("x:\n  k: 1\n", "top-level key 'x' is not a non-negative integer");
    bad("1:\n  k: [1, 2\n", "has no closing ']'");
    bad("1:\n  k: 1\n  k: 2\n", "a.yml:3: duplicated key 'k'");
    bad("1:\n  k: 1\n1:\n  k: 2\n", "duplicated top-level key 1");
    bad("1: {a: 1}\n", "unsupported value");
    bad("  k: 1\n", "before any top-level key");
    bad("- k: 1\n", "before any top-level key");
    bad("1:\n  k: 1\n- j: 2\n", "list item '-' inside a map block");
    bad("1:\n  k: [1, 2] 3\n", "unexpected text after ']'");
    bad("1:\n  k:\n", "key 'k' has no value");
    REQUIRE_THROWS_WITH(parse_int_keyed_yaml(dir + "/none.yml"), Contains("none.yml"));
}
