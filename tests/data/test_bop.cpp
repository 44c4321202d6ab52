// SPDX-License-Identifier: MIT
// BOP reader on the ycbv_mini fixture (always), on copies of it with broken files, and on
// the YCB-V / LM-O subsets in ../shared/data when present.
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.h"
#include "data/bop.h"
#include "testing.h"

namespace fs = std::filesystem;
using Catch::Contains;
using nlohmann::json;
using namespace g2l;
using namespace g2l::data;

namespace {

std::string mini_root() { return g2l::testing::fixture_dir() + "/ycbv_mini"; }
std::string mini_scene() { return mini_root() + "/train_real/000000"; }

json read_json_file(const std::string& path) {
    std::ifstream f(path);
    REQUIRE(f.good());
    return json::parse(f);
}

void write_text(const std::string& path, const std::string& text) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    REQUIRE(f.good());
    f << text;
}

// A writable copy of the fixture; returns its root.
std::string copy_mini(const std::string& tag) {
    const std::string dst = g2l::testing::temp_dir(tag) + "/ycbv_mini";
    fs::copy(mini_root(), dst, fs::copy_options::recursive);
    for (const auto& e : fs::recursive_directory_iterator(dst)) {
        fs::permissions(e.path(), fs::perms::owner_write, fs::perm_options::add);
    }
    return dst;
}

// Edits <root>/train_real/000000/<name> through `edit`.
template <class F>
void edit_json(const std::string& root, const std::string& name, F edit) {
    const std::string path = root + "/train_real/000000/" + name;
    json j = read_json_file(path);
    edit(j);
    write_text(path, j.dump(1));
}

void require_pose_equals_json(const geom::Pose& p, const json& gt) {
    for (int i = 0; i < 9; ++i) CHECK(p.R(i / 3, i % 3) == gt["cam_R_m2c"][i].get<double>());
    for (int i = 0; i < 3; ++i) CHECK(p.t(i) == gt["cam_t_m2c"][i].get<double>());
}

}  // namespace

TEST_CASE("open_bop reads frames, poses, cameras and boxes of the ycbv_mini fixture", "[data]") {
    const BopDataset ds = open_bop(mini_root(), "train_real");
    CHECK(ds.name() == "ycbv_mini");
    CHECK(ds.split() == "train_real");
    REQUIRE(ds.scenes() == std::vector<std::string>{"000000"});
    REQUIRE(ds.frames().size() == 2);
    CHECK(ds.frames()[0].image_id == 1);
    CHECK(ds.frames()[1].image_id == 11);

    const json gt = read_json_file(mini_scene() + "/scene_gt.json");
    const json info = read_json_file(mini_scene() + "/scene_gt_info.json");
    for (const Frame& f : ds.frames()) {
        const std::string key = std::to_string(f.image_id);
        CHECK(f.scene == "000000");
        CHECK(f.K.fx == 1066.778);
        CHECK(f.K.fy == 1067.487);
        CHECK(f.K.cx == 312.9869);
        CHECK(f.K.cy == 241.3109);
        CHECK(f.K.width == 640);
        CHECK(f.K.height == 480);
        CHECK(f.depth_scale == 0.1);
        CHECK(fs::is_regular_file(f.rgb_path));
        CHECK(fs::is_regular_file(f.depth_path));
        REQUIRE(f.instances.size() == 2);
        for (size_t k = 0; k < 2; ++k) {
            const Instance& in = f.instances[k];
            CHECK(in.index_in_frame == static_cast<int>(k));
            CHECK(in.obj_id == gt[key][k]["obj_id"].get<int>());
            require_pose_equals_json(in.pose, gt[key][k]);
            const json& bb = info[key][k]["bbox_visib"];
            CHECK(in.bbox_visib.x == bb[0].get<int>());
            CHECK(in.bbox_visib.y == bb[1].get<int>());
            CHECK(in.bbox_visib.w == bb[2].get<int>());
            CHECK(in.bbox_visib.h == bb[3].get<int>());
            CHECK(in.bbox_obj.empty());   // YCB-V train_real has no bbox_obj
            CHECK(in.visib_fract == -1);  // ... nor visib_fract
            char name[32];
            std::snprintf(name, sizeof(name), "%06d_%06d.png", f.image_id, static_cast<int>(k));
            CHECK(fs::path(in.mask_visib_path).filename().string() == name);
        }
    }
    // Hand-copied from scene_gt.json: frame 1, instance 0 (obj 8).
    const Instance& i0 = ds.frames()[0].instances[0];
    CHECK(i0.obj_id == 8);
    CHECK(i0.pose.R(0, 0) == 0.023388461238133155);
    CHECK(i0.pose.R(2, 2) == 0.5825453120678373);
    CHECK(i0.pose.t.z() == 592.6409962060181);
    CHECK(ds.frames()[0].instances[1].bbox_visib.x == 335);

    REQUIRE(ds.models().size() == 2);
    const ObjectModel& m8 = ds.model(8);
    CHECK(m8.name == "009_gelatin_box");
    CHECK(ds.model(14).name == "025_mug");
    CHECK(m8.info.diameter == 114.053345);
    CHECK(m8.info.min.x() == -46.129999999999995);
    CHECK(m8.info.size.z() == 30.12);
    CHECK_FALSE(m8.info.symmetric);
    CHECK(fs::path(m8.mesh_path).filename() == "obj_000008.ply");
    REQUIRE_THROWS_WITH(ds.model(21), Contains("no object id 21") && Contains("{8, 14}"));
}

TEST_CASE("ycbv_mini images decode to the BOP pixel counts", "[data]") {
    const BopDataset ds = open_bop(mini_root(), "train_real");
    const json info = read_json_file(mini_scene() + "/scene_gt_info.json");
    for (const Frame& f : ds.frames()) {
        int w = 0, h = 0;
        const std::vector<uint16_t> depth = ds.load_depth(f, &w, &h);
        REQUIRE(w == 640);
        REQUIRE(h == 480);
        REQUIRE(depth.size() == 640u * 480u);
        const std::vector<float> mm = ds.load_depth_mm(f, &w, &h);
        CHECK(mm[240 * 640 + 320] == Approx(depth[240 * 640 + 320] * 0.1));
        const Image rgb = ds.load_rgb(f);
        CHECK(rgb.w == 640);
        CHECK(rgb.h == 480);
        CHECK(rgb.channels == 3);
        CHECK(rgb.data.size() == 640u * 480u * 3u);
        for (const Instance& in : f.instances) {
            const Image mask = ds.load_mask(f, in);
            REQUIRE(mask.channels == 1);
            REQUIRE(mask.w == 640);
            REQUIRE(mask.h == 480);
            // px_count_visib = mask pixels; px_count_valid = mask pixels with a depth reading.
            int visib = 0, valid = 0;
            for (size_t i = 0; i < mask.data.size(); ++i) {
                visib += mask.data[i] != 0;
                valid += mask.data[i] != 0 && depth[i] != 0;
            }
            const json& e = info[std::to_string(f.image_id)][in.index_in_frame];
            CHECK(visib == e["px_count_visib"].get<int>());
            CHECK(valid == e["px_count_valid"].get<int>());
        }
    }
}

TEST_CASE("BOP model meshes load once and are cached", "[data]") {
    const BopDataset ds = open_bop(mini_root(), "train_real");
    const geom::Mesh& a = ds.load_model_mesh(8);
    CHECK(a.vertices.rows() == 7866);  // "element vertex 7866" in obj_000008.ply
    CHECK(a.faces.rows() == 15728);
    CHECK(a.colors.rows() == 0);
    const BopDataset copy = ds;
    CHECK(&copy.load_model_mesh(8) == &a);
    REQUIRE_THROWS_WITH(ds.load_model_mesh(3), Contains("no object id 3"));
}

TEST_CASE("BopOptions filter scenes and objects and set symmetric ids", "[data]") {
    BopOptions o;
    o.obj_ids = {14};
    const BopDataset only14 = open_bop(mini_root(), "train_real", o);
    REQUIRE(only14.models().size() == 1);
    REQUIRE(only14.frames().size() == 2);
    for (const Frame& f : only14.frames()) {
        REQUIRE(f.instances.size() == 1);
        CHECK(f.instances[0].obj_id == 14);
        CHECK(f.instances[0].index_in_frame == 1);  // keeps its BOP index (mask file name)
    }
    o = {};
    o.symmetric_ids = std::vector<int>{8};
    const BopDataset sym = open_bop(mini_root(), "train_real", o);
    CHECK(sym.model(8).info.symmetric);
    CHECK_FALSE(sym.model(14).info.symmetric);

    o = {};
    o.scenes = {"000000"};
    CHECK(open_bop(mini_root(), "train_real", o).frames().size() == 2);
    o.scenes = {"000007"};
    REQUIRE_THROWS_WITH(open_bop(mini_root(), "train_real", o),
                        Contains("scene '000007' not found"));
    o = {};
    o.obj_ids = {21};
    REQUIRE_THROWS_WITH(open_bop(mini_root(), "train_real", o),
                        Contains("object id 21") && Contains("models_info.json"));
    o = {};
    o.models_eval = true;
    REQUIRE_THROWS_WITH(open_bop(mini_root(), "train_real", o), Contains("models_eval"));
    REQUIRE_THROWS_WITH(open_bop(mini_root(), "test"), Contains("split 'test' not found"));
    REQUIRE_THROWS_WITH(open_bop(mini_root() + "/nope", "test"), Contains("/nope"));
}

TEST_CASE("symmetric objects come from the data or a named convention, never the folder's name",
          "[data]") {
    CHECK(symmetric_convention("ycbv") == std::vector<int>{13, 16, 19, 20, 21});
    CHECK(symmetric_convention("YCBV") == std::vector<int>{13, 16, 19, 20, 21});
    CHECK(symmetric_convention("lmo") == std::vector<int>{10, 11});
    CHECK(symmetric_convention("lm") == std::vector<int>{10, 11});
    CHECK_THROWS_WITH(symmetric_convention("tless"), Contains("no symmetric-object convention 'tless'"));
    // A models_info.json that declares object 14 symmetric, in folders of any name: the same
    // flags ("ycbv_mini" once guessed 13, 16, 19, 20, 21 from its name).
    for (const char* name : {"ycbv", "lm_copy", "my_parts"}) {
        const std::string root = g2l::testing::temp_dir("symnames") + "/" + name;
        std::filesystem::copy(mini_root(), root, std::filesystem::copy_options::recursive);
        json info = json::parse(std::ifstream(root + "/models/models_info.json"));
        info["14"]["symmetries_continuous"] = json::array({{{"axis", {0, 0, 1}}, {"offset", {0, 0, 0}}}});
        std::ofstream(root + "/models/models_info.json") << info.dump();
        const BopDataset ds = open_bop(root, "train_real");
        INFO(name);
        CHECK(ds.model(14).info.symmetric);
        CHECK_FALSE(ds.model(8).info.symmetric);
    }
    CHECK(default_object_name("lmo", 1) == "ape");
    CHECK(default_object_name("lm", 15) == "phone");
    CHECK(default_object_name("ycbv", 1).empty());
}

TEST_CASE("open_bop errors name the file and key of a broken fixture copy", "[data]") {
    SECTION("missing scene_camera.json") {
        const std::string r = copy_mini("bop_nocam");
        fs::remove(r + "/train_real/000000/scene_camera.json");
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("no such file") && Contains("scene_camera.json"));
    }
    SECTION("truncated scene_gt.json") {
        const std::string r = copy_mini("bop_trunc");
        const std::string p = r + "/train_real/000000/scene_gt.json";
        fs::resize_file(p, fs::file_size(p) / 2);
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("invalid JSON at byte") && Contains("scene_gt.json"));
    }
    SECTION("missing cam_K") {
        const std::string r = copy_mini("bop_nok");
        edit_json(r, "scene_camera.json", [](json& j) { j["11"].erase("cam_K"); });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("scene_camera.json") && Contains("'11.cam_K' is required"));
    }
    SECTION("cam_t_m2c of the wrong length") {
        const std::string r = copy_mini("bop_len");
        edit_json(r, "scene_gt.json", [](json& j) { j["1"][1]["cam_t_m2c"].erase(2); });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"), Contains("scene_gt.json") &&
                                                           Contains("'1[1].cam_t_m2c' must be an array of 3 numbers, got ["));
    }
    SECTION("a string inside cam_K") {
        const std::string r = copy_mini("bop_str");
        edit_json(r, "scene_camera.json", [](json& j) { j["1"]["cam_K"][4] = "NaN"; });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("'1.cam_K[4]' must be a number, got \"NaN\""));
    }
    SECTION("image id of scene_gt.json missing from scene_camera.json") {
        const std::string r = copy_mini("bop_noid");
        edit_json(r, "scene_camera.json", [](json& j) { j.erase("11"); });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("scene_camera.json: image id 11") && Contains("missing"));
    }
    SECTION("scene_gt_info.json lists fewer instances") {
        const std::string r = copy_mini("bop_info");
        edit_json(r, "scene_gt_info.json", [](json& j) { j["11"].erase(1); });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("scene_gt_info.json") && Contains("lists 1 instances"));
    }
    SECTION("cam_R_m2c that is not a rotation") {
        const std::string r = copy_mini("bop_rot");
        edit_json(r, "scene_gt.json", [](json& j) { j["11"][0]["cam_R_m2c"][0] = 2.0; });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("'11[0].cam_R_m2c' is not a rotation"));
    }
    SECTION("an instance whose object has no model") {
        const std::string r = copy_mini("bop_obj");
        edit_json(r, "scene_gt.json", [](json& j) { j["1"][0]["obj_id"] = 21; });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("'1[0].obj_id': object 21 has no model"));
    }
    SECTION("a non-numeric image id") {
        const std::string r = copy_mini("bop_key");
        edit_json(r, "scene_gt.json", [](json& j) { j["x1"] = j["1"]; });
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("key \"x1\" is not a non-negative image id"));
    }
    SECTION("a deleted mask and a deleted depth image") {
        const std::string r = copy_mini("bop_mask");
        fs::remove(r + "/train_real/000000/mask_visib/000011_000001.png");
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"),
                            Contains("mask_visib") && Contains("000011_000001.png"));
        fs::remove_all(r + "/train_real/000000/mask_visib");  // no folder: no masks, no error
        CHECK(open_bop(r, "train_real").frames()[1].instances[1].mask_visib_path.empty());
        fs::remove(r + "/train_real/000000/depth/000001.png");
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"), Contains("depth") && Contains("000001.png"));
    }
    SECTION("a missing model file") {
        const std::string r = copy_mini("bop_ply");
        fs::remove(r + "/models/obj_000014.ply");
        REQUIRE_THROWS_WITH(open_bop(r, "train_real"), Contains("obj_000014.ply"));
    }
}

TEST_CASE("image loaders reject missing, truncated and 8-bit depth files", "[data]") {
    const std::string r = copy_mini("bop_img");
    const BopDataset ds = open_bop(r, "train_real");
    const Frame& f0 = ds.frames()[0];
    const Frame& f1 = ds.frames()[1];
    int w = 0, h = 0;
    // Truncated PNG: the decoder must fail, not return a partial image.
    fs::resize_file(f0.depth_path, fs::file_size(f0.depth_path) / 3);
    REQUIRE_THROWS_WITH(ds.load_depth(f0, &w, &h),
                        Contains("could not be decoded") && Contains(f0.depth_path));
    // An 8-bit RGB image where a 16-bit depth is expected.
    fs::copy_file(f1.rgb_path, f1.depth_path, fs::copy_options::overwrite_existing);
    REQUIRE_THROWS_WITH(ds.load_depth(f1, &w, &h), Contains("16-bit single-channel") &&
                                                       Contains("8-bit unsigned with 3") &&
                                                       Contains(f1.depth_path));
    fs::remove(f1.rgb_path);
    REQUIRE_THROWS_WITH(ds.load_rgb(f1), Contains("not found") && Contains(f1.rgb_path));
    write_text(f1.instances[0].mask_visib_path, "not a png");
    REQUIRE_THROWS_WITH(ds.load_mask(f1, f1.instances[0]),
                        Contains("could not be decoded") && Contains("000011_000000.png"));
    // A frame whose camera says 320x240 must reject a 640x480 image.
    Frame small = f0;
    small.K.width = 320;
    small.K.height = 240;
    REQUIRE_THROWS_WITH(ds.load_mask(small, small.instances[0]),
                        Contains("is 640x480") && Contains("320x240"));
    Frame nodepth = f0;
    nodepth.depth_path.clear();
    REQUIRE_THROWS_WITH(ds.load_depth(nodepth, &w, &h), Contains("no depth image"));
    // A truncated model file fails when the mesh is first needed, naming the file.
    fs::resize_file(ds.model(14).mesh_path, 1000);
    REQUIRE_THROWS_WITH(ds.load_model_mesh(14), Contains("obj_000014.ply"));
}

TEST_CASE("RGB loader returns R, G, B order and save_png round-trips", "[data]") {
    const std::string dir = g2l::testing::temp_dir("rgb_order");
    // A 2x1 binary PPM (P6 stores R, G, B): pixel 0 pure red, pixel 1 (10, 20, 30).
    const std::string ppm = dir + "/two.ppm";
    write_text(ppm, std::string("P6\n2 1\n255\n") + std::string("\xff\x00\x00\x0a\x14\x1e", 6));
    const Image im = load_rgb_image(ppm);
    REQUIRE(im.w == 2);
    REQUIRE(im.channels == 3);
    CHECK(im.at(0, 0, 0) == 255);
    CHECK(im.at(0, 0, 1) == 0);
    CHECK(im.at(1, 0, 0) == 10);
    CHECK(im.at(1, 0, 2) == 30);
    save_png(dir + "/two.png", im);
    const Image back = load_rgb_image(dir + "/two.png");
    CHECK(back.data == im.data);
    int w = 0, h = 0;
    image_size(dir + "/two.png", &w, &h);
    CHECK((w == 2 && h == 1));
    const std::vector<uint16_t> d = {0, 1, 65535, 1234, 7, 40000};
    save_depth_png(dir + "/d.png", d.data(), 3, 2);
    CHECK(load_depth_png(dir + "/d.png", &w, &h) == d);
    CHECK((w == 3 && h == 2));
    Image bad = im;
    bad.data.pop_back();
    REQUIRE_THROWS_WITH(save_png(dir + "/bad.png", bad), Contains("expected w*h*channels = 6"));
}

TEST_CASE("open_bop reads the 60 YCB-V train_real frames of ../shared", "[data][shared]") {
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) return g2l::testing::skip_without_shared_data("YCB-V BOP reader test");
    const BopDataset ds = open_bop(*shared + "/ycbv", "train_real");
    CHECK(ds.name() == "ycbv");
    REQUIRE(ds.frames().size() == 60);
    CHECK(ds.models().size() == 21);
    CHECK(ds.model(1).name == "002_master_chef_can");
    // ../shared's models_info.json declares no symmetries (the YCB-Video convention is asked
    // for by name: g2l_eval --symmetric ycbv).
    for (const auto& [id, m] : ds.models()) CHECK_FALSE(m.info.symmetric);
    BopOptions conv;
    conv.symmetric_ids = symmetric_convention("ycbv");
    const BopDataset named = open_bop(*shared + "/ycbv", "train_real", conv);
    for (int id : {13, 16, 19, 20, 21}) CHECK(named.model(id).info.symmetric);
    CHECK_FALSE(named.model(1).info.symmetric);
    const std::map<std::string, std::set<int>> expected = {
        {"000000", {8, 14, 21}}, {"000001", {1, 2, 3, 5}}, {"000002", {5, 7, 9, 10, 16, 18}}};
    std::map<std::string, std::set<int>> seen;
    for (const Frame& f : ds.frames()) {
        for (const Instance& in : f.instances) seen[f.scene].insert(in.obj_id);
        CHECK(!f.depth_path.empty());
    }
    CHECK(seen == expected);
    // The fixture's re-encoded depth is pixel-identical to the original.
    int w = 0, h = 0, w2 = 0, h2 = 0;
    const BopDataset mini = open_bop(mini_root(), "train_real");
    CHECK(ds.load_depth(ds.frames()[0], &w, &h) == mini.load_depth(mini.frames()[0], &w2, &h2));
}

TEST_CASE("open_bop reads LM-O test (RGB only, coloured models)", "[data][shared]") {
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) return g2l::testing::skip_without_shared_data("LM-O BOP reader test");
    const std::string root = *shared + "/lmo";
    const BopDataset ds = open_bop(root, "test");
    REQUIRE(ds.frames().size() == 100);
    const json gt = read_json_file(root + "/test/000002/scene_gt.json");
    const json info = read_json_file(root + "/test/000002/scene_gt_info.json");
    size_t n_inst = 0;
    for (const Frame& f : ds.frames()) {
        CHECK(f.depth_path.empty());
        CHECK(fs::is_regular_file(f.rgb_path));
        CHECK(f.K.fx == 572.4114);
        CHECK(f.K.cy == 242.04899);
        CHECK(f.depth_scale == 1.0);
        const std::string key = std::to_string(f.image_id);
        REQUIRE(f.instances.size() == gt[key].size());
        for (const Instance& in : f.instances) {
            const json& e = info[key][in.index_in_frame];
            CHECK(in.visib_fract == e["visib_fract"].get<double>());
            CHECK(in.bbox_obj.w == e["bbox_obj"][2].get<int>());
            CHECK(in.bbox_visib.h == e["bbox_visib"][3].get<int>());
            CHECK(in.mask_visib_path.empty());
            require_pose_equals_json(in.pose, gt[key][in.index_in_frame]);
        }
        n_inst += f.instances.size();
    }
    size_t n_json = 0;
    for (const auto& kv : gt.items()) n_json += kv.value().size();
    CHECK(n_inst == n_json);
    CHECK(n_inst > 100);  // several objects per image
    int w = 0, h = 0;
    REQUIRE_THROWS_WITH(ds.load_depth(ds.frames()[0], &w, &h), Contains("no depth image"));
    REQUIRE(ds.models().size() == 8);
    CHECK(ds.model(1).name == "ape");
    CHECK(ds.model(10).info.symmetric);
    CHECK(ds.model(11).info.symmetric);
    CHECK_FALSE(ds.model(12).info.symmetric);
    const geom::Mesh& ape = ds.load_model_mesh(1);
    CHECK(ape.vertices.rows() == 5841);  // "element vertex 5841" in obj_000001.ply
    CHECK(ape.colors.rows() == 5841);
    CHECK(ape.normals.rows() == 5841);
    CHECK(int(ape.colors(0, 0)) == 148);  // first vertex: ... 148 57 57 255
    BopOptions eval;
    eval.models_eval = true;
    const BopDataset dse = open_bop(root, "test", eval);
    CHECK(fs::path(dse.model(5).mesh_path).parent_path().filename() == "models_eval");
}

TEST_CASE("camera files: the one reader of BOP camera.json and scene_camera.json", "[data]") {
    using g2l::data::CameraFile;
    using g2l::data::parse_camera_file;
    // BOP camera.json: fx/fy/cx/cy, depth_scale, the image size
    const CameraFile a = parse_camera_file(
        R"({"cx": 312.98, "cy": 241.31, "depth_scale": 0.1, "fx": 1066.778, "fy": 1067.487,
            "height": 480, "width": 640})", "cam");
    CHECK(a.fx == 1066.778);
    CHECK(a.fy == 1067.487);
    CHECK(a.cx == 312.98);
    CHECK(a.cy == 241.31);
    CHECK(a.depth_scale == 0.1);
    CHECK(a.width == 640);
    CHECK(a.height == 480);
    // one scene_camera.json entry (other BOP keys accepted), and a whole file with an image id
    const std::string entry =
        R"({"cam_K": [500, 0, 320, 0, 510, 240, 0, 0, 1], "depth_scale": 1, "elev": 10,
            "cam_R_w2c": [1, 0, 0, 0, 1, 0, 0, 0, 1]})";
    const CameraFile b = parse_camera_file(entry, "cam");
    CHECK(b.fx == 500);
    CHECK(b.fy == 510);
    CHECK(b.cx == 320);
    CHECK(b.cy == 240);
    CHECK(b.depth_scale == 1);
    CHECK(b.width == 0);  // not given
    const CameraFile c = parse_camera_file(R"({"3": )" + entry + "}", "cam", 3);
    CHECK(c.fy == 510);
    // the fixture's own files, through the file reader
    const CameraFile d =
        g2l::data::load_camera_file(mini_root() + "/train_real/000000/scene_camera.json", 1);
    CHECK(d.depth_scale == 0.1);
    CHECK(d.fx == Approx(1066.778).epsilon(0).margin(1e-9));
    CHECK(g2l::data::load_camera_file(mini_root() + "/camera.json").width == 640);

    auto bad = [](const std::string& text, int id, const std::string& what) {
        INFO(text);
        REQUIRE_THROWS_WITH(parse_camera_file(text, "camera 'c.json'", id),
                            Contains("camera 'c.json'") && Contains(what));
    };
    bad("[1]", -1, "the top level must be a JSON object");
    bad(R"({"1": {}})", -1, "give the image id (--image-id)");
    bad(R"({"1": {}})", 2, "no entry for image 2");
    bad(R"({"1": {"depth_scale": 1}})", 1, "'1.cam_K' is required");
    bad(R"({"fx": 500, "fy": 500, "cx": 320, "cy": 240})", -1,
        "'depth_scale' is required (mm per unit of the depth PNG");
    bad(R"({"fx": 500, "fy": 500, "cx": 320, "depth_scale": 1})", -1, "'cy' is required");
    bad(R"({"fx": 0, "fy": 500, "cx": 320, "cy": 240, "depth_scale": 1})", -1,
        "focal lengths must be > 0, got fx=0");
    bad(R"({"fx": 500, "fy": 500, "cx": 320, "cy": 240, "depth_scale": -0.1})", -1,
        "'depth_scale' must be > 0, got -0.1");
    bad(R"({"fx": 500, "fy": 500, "cx": 320, "cy": "240", "depth_scale": 1})", -1,
        "'cy' must be a number, got \"240\"");
    bad(R"({"fx": 500, "fy": 500, "cx": 320, "cy": 240, "depth_scale": 1, "width": 640.5})", -1,
        "'width' must be an integer");
    bad(R"({"cam_K": [500, 3, 320, 0, 500, 240, 0, 0, 1], "depth_scale": 1})", -1, "'cam_K'");
    bad(R"({"cam_K": [500, 0, 320, 0, 500, 240], "depth_scale": 1})", -1,
        "'cam_K' must be an array of 9 numbers");
    REQUIRE_THROWS_WITH(g2l::data::load_camera_file("/nonexistent/cam.json"),
                        Contains("camera file not found: '/nonexistent/cam.json'"));
}

TEST_CASE("a models_info diameter that disagrees with the mesh is an error naming both",
          "[data]") {
    const std::string root = copy_mini("bop_units");
    const std::string info = root + "/models/models_info.json";
    json j = read_json_file(info);
    j["8"]["diameter"] = 1140.53345;  // x10: a unit slip
    write_text(info, j.dump(1));
    BopOptions o;
    const Dataset ds = open_bop_models(root, o);
    REQUIRE_THROWS_WITH(ds.load_model_mesh(8),
                        Contains("obj_000008.ply' measures 114.05") &&
                            Contains("models_info of dataset '" + root + "' (object 8) declares "
                                     "diameter 1140.5") &&
                            Contains("centimetre / millimetre slip"));
    REQUIRE(ds.load_model_mesh(14).vertices.rows() > 0);  // its entry is right
}

TEST_CASE("a folder of meshes given as a models root says how to make one", "[data]") {
    const std::string dir = g2l::testing::temp_dir("bop_meshes_only");
    fs::copy_file(mini_root() + "/models/obj_000008.ply", dir + "/part.ply");
    REQUIRE_THROWS_WITH(open_bop_models(dir, {}),
                        Contains("BOP models folder not found: '" + dir + "/models'") &&
                            Contains("'g2l_render --models DIR --out ROOT --frames 1' writes one"));
    fs::create_directories(dir + "/models");
    REQUIRE_THROWS_WITH(open_bop_models(dir, {}),
                        Contains("models_info.json'") && Contains("g2l_render --models DIR"));
}
