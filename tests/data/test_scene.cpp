// SPDX-License-Identifier: MIT
// Scene generator, scene config JSON and BOP writer tests (round trip through data/bop.h).
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <Eigen/Eigenvalues>

#include "core/error.h"
#include "data/bop.h"
#include "data/bop_writer.h"
#include "data/render_primitives.h"
#include "data/scene.h"
#include "testing.h"

using namespace g2l;
using namespace g2l::data;
using Catch::Contains;
namespace fs = std::filesystem;

namespace {

struct Models {
    geom::Mesh a = make_box(80, 60, 40), b = make_icosphere(35, 2), c = make_box(30, 30, 90);
    std::vector<SceneModel> list() const { return {{1, &a}, {2, &b}, {5, &c}}; }
};

SceneConfig small_config() {
    SceneConfig cfg;
    cfg.camera = {400, 400, 160.5, 120.5, 320, 240};
    cfg.targets_min = 2;
    cfg.targets_max = 3;
    cfg.seed = 11;
    return cfg;
}

std::string read_bytes(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
}

}  // namespace

TEST_CASE("scene ground truth is consistent with the masks, occluded objects lose pixels",
          "[data][scene]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.xy_frac = 0.15;  // crowd the objects so they occlude each other
    cfg.separation = 0.3;
    cfg.z_min = 600;
    cfg.z_max = 900;
    cfg.noise.enabled = false;
    SceneGenerator gen(cfg, m.list());
    Renderer solo_renderer(cfg.camera);
    RenderOutput solo;
    RenderedFrame f;
    int occluded = 0;
    for (int64_t idx = 0; idx < 6; ++idx) {
        gen.render_frame(idx, f);
        REQUIRE(f.instances.size() >= 2);
        REQUIRE(f.instances.size() <= 3);
        std::vector<std::vector<float>> solo_depth;
        for (size_t k = 0; k < f.instances.size(); ++k) {
            const RenderedInstance& gt = f.instances[k];
            const geom::Mesh* mesh = gt.obj_id == 1 ? &m.a : gt.obj_id == 2 ? &m.b : &m.c;
            solo_renderer.render({RenderObject{mesh, gt.pose, 1, {}}}, RenderOptions{}, solo);
            solo_depth.push_back(solo.depth);
            int64_t all = 0, visib = 0;
            for (size_t i = 0; i < solo.depth.size(); ++i) {
                all += solo.depth[i] > 0;
                visib += f.mask[i] == k + 1;
                if (f.mask[i] == k + 1) REQUIRE(solo.depth[i] > 0);  // visible part of the full
                if (f.mask[i] == k + 1) REQUIRE(f.depth[i] == solo.depth[i]);
            }
            CHECK(gt.px_count_all == all);
            CHECK(gt.px_count_visib == visib);
            CHECK(gt.px_count_valid <= gt.px_count_all);
            CHECK(gt.visib_fract == Approx(double(visib) / double(all)));
            CHECK(gt.bbox_visib.w <= gt.bbox_obj.w);
            occluded += gt.visib_fract < 0.98;
        }
        // Where two silhouettes overlap, the instance with the smaller solo depth is the one
        // marked visible (unless a distractor or the plane is in front of both).
        for (size_t i = 0; i < f.mask.size(); ++i) {
            size_t best = 0;
            float zbest = 1e30f;
            int covering = 0;
            for (size_t k = 0; k < solo_depth.size(); ++k) {
                if (solo_depth[k][i] > 0 && solo_depth[k][i] < zbest) zbest = solo_depth[k][i], best = k;
                covering += solo_depth[k][i] > 0;
            }
            if (covering >= 2 && f.mask[i] != 0) REQUIRE(f.mask[i] == best + 1);
        }
    }
    CHECK(occluded >= 2);
}

TEST_CASE("scene distractors never repeat a target of the frame", "[data][scene]") {
    // LINEMOD-like scenes list every object as target and as distractor: an unannotated copy
    // of the frame's annotated object would teach "this object is background".
    Models m;
    SceneConfig cfg = small_config();
    cfg.target_obj_ids = {1};
    cfg.targets_min = cfg.targets_max = 1;
    cfg.distractor_obj_ids = {1};  // only the target itself: no distractor can be drawn
    cfg.distractors_min = cfg.distractors_max = 2;
    cfg.support_plane_prob = 0;
    cfg.noise.enabled = false;
    RenderedFrame f;
    for (const char* mode : {"random", "resting"}) {
        cfg.pose_mode = mode;
        SceneGenerator gen(cfg, m.list());
        for (int64_t idx = 0; idx < 3; ++idx) {
            gen.render_frame(idx, f);
            REQUIRE(f.instances.size() == 1);
            CHECK(std::count(f.distractor_mask.begin(), f.distractor_mask.end(), 255) == 0);
        }
        // With another object in the list, the distractors are that one.
        cfg.distractor_obj_ids = {1, 2};
        SceneGenerator gen2(cfg, m.list());
        int64_t px = 0;
        for (int64_t idx = 0; idx < 3; ++idx) {
            gen2.render_frame(idx, f);
            px += std::count(f.distractor_mask.begin(), f.distractor_mask.end(), 255);
        }
        CHECK(px > 0);
        cfg.distractor_obj_ids = {1};
    }
}

TEST_CASE("scene distractors: their pixels are in distractor_mask, never in the instance mask",
          "[data][scene]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.target_obj_ids = {1};
    cfg.targets_min = cfg.targets_max = 1;
    cfg.distractor_obj_ids = {2, 5};
    cfg.distractors_min = cfg.distractors_max = 2;
    cfg.support_plane_prob = 0;
    cfg.random_background = false;
    cfg.noise.enabled = false;
    for (const char* mode : {"random", "resting"}) {
        cfg.pose_mode = mode;
        SceneGenerator gen(cfg, m.list());
        RenderedFrame f;
        int64_t distractor_px = 0;
        for (int64_t idx = 0; idx < 4; ++idx) {
            gen.render_frame(idx, f);
            REQUIRE(f.distractor_mask.size() == f.mask.size());
            REQUIRE(f.instances.size() == 1);
            REQUIRE(f.instances[0].obj_id == 1);
            // No block in this scene: distractors are not blocks.
            REQUIRE(std::count(f.block_mask.begin(), f.block_mask.end(), 255) == 0);
            for (size_t i = 0; i < f.mask.size(); ++i) {
                REQUIRE(f.mask[i] <= 1);  // only the one target's id
                if (f.distractor_mask[i]) {
                    REQUIRE(f.distractor_mask[i] == 255);
                    REQUIRE(f.mask[i] == 0);
                    REQUIRE(f.depth[i] > 0);  // a surface, not the background
                    ++distractor_px;
                }
            }
            // Without a plane or table (random mode), every surface pixel is the target's or
            // a distractor's.
            if (std::string(mode) == "random")
                for (size_t i = 0; i < f.mask.size(); ++i)
                    if (f.depth[i] > 0) REQUIRE((f.mask[i] == 1 || f.distractor_mask[i] == 255));
        }
        INFO(mode);
        CHECK(distractor_px > 500);
    }
}

TEST_CASE("scene frames depend only on seed and index, not on threads or order",
          "[data][scene]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.distractors_max = 1;
    SceneGenerator g1(cfg, m.list()), g2(cfg, m.list());
    RenderedFrame a, b;
    g1.render_frame(3, a, 1);
    g2.render_frame(0, b, 2);  // a different frame first
    g2.render_frame(3, b, 2);
    CHECK(a.depth == b.depth);
    CHECK(a.rgb == b.rgb);
    CHECK(a.mask == b.mask);
    REQUIRE(a.instances.size() == b.instances.size());
    for (size_t k = 0; k < a.instances.size(); ++k) {
        CHECK(a.instances[k].pose.R == b.instances[k].pose.R);
        CHECK(a.instances[k].pose.t == b.instances[k].pose.t);
    }
    g1.render_frame(4, b, 1);
    CHECK(a.depth != b.depth);
    // Objects sit in the configured depth range (pose t is the bounding-box centre here).
    for (const RenderedInstance& in : a.instances) {
        CHECK(in.pose.t.z() >= cfg.z_min);
        CHECK(in.pose.t.z() <= cfg.z_max);
    }
}

TEST_CASE("BOP writer output reads back with the BOP reader", "[data][scene][bop]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.target_obj_ids = {1, 5};
    SceneGenerator gen(cfg, m.list());
    const fs::path root = testing::temp_dir("render_bop");
    write_bop_models((root / "models").string(), m.list());
    std::vector<RenderedFrame> frames(2);
    {
        BopSceneWriter w((root / "train_synt" / "000000").string(), 3);
        for (int i = 0; i < 2; ++i) {
            gen.render_frame(i, frames[size_t(i)]);
            w.write(i, frames[size_t(i)]);
        }
        w.flush();
        REQUIRE_THROWS_WITH(w.write(1, frames[1]), Contains("image id 1 written twice"));
        // Flushed but not finished (a render killed here): the reader refuses the scene,
        // saying how far it got and what to do.
        REQUIRE_THROWS_WITH(open_bop(root.string(), "train_synt"),
                            Contains("000000' was not finished: its render stopped with 2 of 3 "
                                     "frames listed") && Contains("g2l_render --force"));
        w.finish();
        REQUIRE(!fs::exists(root / "train_synt" / "000000" / kIncompleteMarker));
    }
    const BopDataset ds = open_bop(root.string(), "train_synt");
    REQUIRE(ds.frames().size() == 2);
    CHECK(ds.models().size() == 3);
    CHECK(ds.model(2).info.diameter == Approx(70).epsilon(1e-4));
    for (int i = 0; i < 2; ++i) {
        const Frame& fr = ds.frames()[size_t(i)];
        const RenderedFrame& src = frames[size_t(i)];
        CHECK(fr.image_id == i);
        CHECK(fr.K.fx == 400);
        CHECK(fr.K.cx == 160.5);
        CHECK(fr.depth_scale == 0.1);
        REQUIRE(fr.instances.size() == src.instances.size());
        int w = 0, h = 0;
        const std::vector<uint16_t> depth = ds.load_depth(fr, &w, &h);
        REQUIRE(w == 320);
        REQUIRE(h == 240);
        for (size_t p = 0; p < depth.size(); p += 7) {
            REQUIRE(depth[p] == uint16_t(std::lround(src.depth[p] / 0.1)));
        }
        for (size_t k = 0; k < fr.instances.size(); ++k) {
            const Instance& in = fr.instances[k];
            const RenderedInstance& gt = src.instances[k];
            CHECK(in.obj_id == gt.obj_id);
            CHECK((in.pose.R - gt.pose.R).cwiseAbs().maxCoeff() < 1e-12);
            CHECK((in.pose.t - gt.pose.t).cwiseAbs().maxCoeff() < 1e-9);
            CHECK(in.visib_fract == Approx(gt.visib_fract));
            CHECK(in.bbox_visib.x == gt.bbox_visib.x);
            CHECK(in.bbox_obj.h == gt.bbox_obj.h);
            const Image mask = ds.load_mask(fr, in);
            int64_t diff = 0;
            for (size_t p = 0; p < src.mask.size(); ++p) {
                diff += (mask.data[p] != 0) != (src.mask[p] == k + 1);
            }
            CHECK(diff == 0);
        }
    }
    // Same seed, other thread count: identical files byte for byte.
    const fs::path root2 = testing::temp_dir("render_bop2");
    BopSceneWriter w2((root2 / "000000").string());
    SceneGenerator gen2(cfg, m.list());
    RenderedFrame f;
    for (int i = 0; i < 2; ++i) {
        gen2.render_frame(i, f, i == 0 ? 1 : 2);
        w2.write(i, f);
    }
    w2.finish();
    for (const char* file : {"scene_gt.json", "scene_gt_info.json", "scene_camera.json",
                             "depth/000001.png", "rgb/000000.png", "mask/000001_000000.png"}) {
        INFO(file);
        CHECK(read_bytes(root / "train_synt" / "000000" / file) ==
              read_bytes(root2 / "000000" / file));
    }
    fs::remove_all(root);
    fs::remove_all(root2);
}

TEST_CASE("scene config JSON round-trips and rejects bad keys and values", "[data][scene]") {
    SceneConfig c = small_config();
    c.target_obj_ids = {3, 4};
    c.noise.sigma_a_mm = 0.7;
    c.euler_min = {-10, -20, -30};
    c.full_rotation = false;
    c.seed = 123456789012345ull;
    const SceneConfig r = parse_scene_config(scene_config_to_json(c), "mem");
    CHECK(scene_config_to_json(r) == scene_config_to_json(c));
    CHECK(r.target_obj_ids == std::vector<int>{3, 4});
    CHECK(r.noise.sigma_a_mm == 0.7);
    CHECK(r.camera.width == 320);
    CHECK(r.seed == 123456789012345ull);

    REQUIRE_THROWS_WITH(parse_scene_config(R"({"z_min": 1500, "z_max": 500})", "s.json"),
                        Contains("z range inverted: z_min 1500 > z_max 500"));
    REQUIRE_THROWS_WITH(parse_scene_config(R"({"zmin": 1})", "s.json"),
                        Contains("s.json: unknown key 'zmin'"));
    REQUIRE_THROWS_WITH(parse_scene_config(R"({"noise": {"sigma_a_mm": "big"}})", "s.json"),
                        Contains("s.json: 'noise.sigma_a_mm' must be a number, got \"big\""));
    REQUIRE_THROWS_WITH(parse_scene_config(R"({"targets_max": 2.5})", "s.json"),
                        Contains("s.json: 'targets_max' must be an integer in the range of 32 bits, got 2.5"));
    REQUIRE_THROWS_WITH(parse_scene_config("{\"z_min\": ", "s.json"),
                        Contains("s.json: invalid JSON"));
    REQUIRE_THROWS_WITH(parse_scene_config(R"({"xy_frac": 0})", "s.json"),
                        Contains("xy_frac must be in (0, 1], got 0"));
    REQUIRE_THROWS_WITH(load_scene_config("/nonexistent/scene.json"),
                        Contains("/nonexistent/scene.json"));
}

TEST_CASE("scene generator rejects missing meshes, empty lists and unknown ids",
          "[data][scene]") {
    Models m;
    SceneConfig cfg = small_config();
    REQUIRE_THROWS_WITH(SceneGenerator(cfg, {}), Contains("empty model list"));
    REQUIRE_THROWS_WITH(SceneGenerator(cfg, {{4, nullptr}}), Contains("obj_id 4 has a null mesh"));
    REQUIRE_THROWS_WITH(SceneGenerator(cfg, {{1, &m.a}, {1, &m.b}}),
                        Contains("duplicated obj_id 1"));
    cfg.target_obj_ids = {1, 7};
    REQUIRE_THROWS_WITH(SceneGenerator(cfg, m.list()),
                        Contains("target obj_id 7 is not among the models (1, 2, 5)"));
    cfg = small_config();
    cfg.z_min = 900;
    cfg.z_max = 400;
    REQUIRE_THROWS_WITH(SceneGenerator(cfg, m.list()), Contains("z_min 900 > z_max 400"));
    cfg = small_config();
    cfg.targets_min = 3;
    cfg.targets_max = 1;
    REQUIRE_THROWS_WITH(SceneGenerator(cfg, m.list()), Contains("got 3 and 1"));
}

TEST_CASE("resting mode: objects lie on one table in stable poses, camera above within range",
          "[data][scene]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.pose_mode = "resting";
    cfg.noise.enabled = false;
    cfg.distractors_max = 0;
    cfg.camera_distance = {600, 900};
    cfg.camera_elevation = {20, 70};
    cfg.camera_roll_max = 10;
    SceneGenerator gen(cfg, m.list());
    RenderedFrame f;
    const double deg = 180.0 / 3.14159265358979323846;
    for (int64_t idx = 0; idx < 8; ++idx) {
        gen.render_frame(idx, f);
        REQUIRE(f.instances.size() >= 2);
        // The table: a plane fitted to the pixels with depth that belong to no object.
        const geom::Intrinsics& K = f.K;
        std::vector<Eigen::Vector3d> table;
        for (int v = 0; v < K.height; v += 3)
            for (int u = 0; u < K.width; u += 3) {
                const size_t i = size_t(v) * K.width + u;
                const double z = f.depth[i];
                if (z > 0 && f.mask[i] == 0)
                    table.emplace_back((u + 0.5 - K.cx) * z / K.fx, (v + 0.5 - K.cy) * z / K.fy, z);
            }
        REQUIRE(table.size() > 100);
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& p : table) mean += p;
        mean /= double(table.size());
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        for (const auto& p : table) cov += (p - mean) * (p - mean).transpose();
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
        Eigen::Vector3d up = es.eigenvectors().col(0);
        if (up.dot(-mean) < 0) up = -up;  // towards the camera, which is above the table
        double off = 0;
        for (const auto& p : table) off = std::max(off, std::fabs(up.dot(p - mean)));
        CHECK(off < 2.0);  // a plane (depth is float and the quad is exact)
        // Every object touches it from above, boxes with a face flat on it.
        for (const auto& gt : f.instances) {
            const geom::Mesh* mesh = gt.obj_id == 1 ? &m.a : gt.obj_id == 2 ? &m.b : &m.c;
            double lo = 1e9;
            for (int64_t v = 0; v < mesh->vertices.rows(); ++v)
                lo = std::min(lo, up.dot(gt.pose.R * mesh->vertices.row(v).cast<double>().transpose() +
                                         gt.pose.t - mean));
            CHECK(lo == Approx(0.0).margin(1.5));
            if (gt.obj_id != 2) {
                double best = 0;
                for (int a = 0; a < 3; ++a) best = std::max(best, std::fabs(up.dot(gt.pose.R.col(a))));
                CHECK(best == Approx(1.0).margin(1e-3));
            }
        }
        const double elevation = std::asin(-up.z()) * deg;  // camera above the table
        CHECK(elevation >= 20 - 1e-6);
        CHECK(elevation <= 70 + 1e-6);
        const double roll = std::atan2(up.x(), -up.y()) * deg;  // image "up" is -y
        CHECK(std::fabs(roll) <= 10 + 1e-6);
        // The table gives depth around the objects: most of the image has a measurement.
        int64_t with_depth = 0;
        for (float z : f.depth) with_depth += z > 0;
        CHECK(double(with_depth) / double(f.depth.size()) > 0.5);
    }
}

TEST_CASE("resting mode: upright_prob stands targets as modelled (model +z up)", "[data][scene]") {
    // Boxes 1 (80 x 60 x 40) and 5 (30 x 30 x 90, standing on its small face is its least
    // stable pose): with upright_prob 1 both stand with their model +z along the table's up,
    // so their +z axes agree in every frame; with the drop prior alone they often do not.
    Models m;
    SceneConfig cfg = small_config();
    cfg.pose_mode = "resting";
    cfg.noise.enabled = false;
    cfg.distractors_max = 0;
    cfg.targets_min = 3;
    cfg.unique_targets = true;
    RenderedFrame f;
    int frames_apart = 0;
    for (const double prob : {1.0, 0.0}) {
        cfg.upright_prob = prob;
        SceneGenerator gen(cfg, m.list());
        int both = 0;
        for (int64_t idx = 0; idx < 24; ++idx) {
            gen.render_frame(idx, f);
            const data::RenderedInstance *a = nullptr, *c = nullptr;
            for (const auto& gt : f.instances) {
                if (gt.obj_id == 1) a = &gt;
                if (gt.obj_id == 5) c = &gt;
            }
            REQUIRE((a && c));
            ++both;
            const double agree = a->pose.R.col(2).dot(c->pose.R.col(2));
            if (prob == 1.0) {
                INFO("frame " << idx);
                CHECK(agree == Approx(1.0).margin(1e-6));
            } else {
                frames_apart += agree < 0.9;
            }
        }
        REQUIRE(both == 24);
    }
    CHECK(frames_apart >= 12);  // without it box 5 mostly lies on a side
    CHECK_THROWS_WITH(parse_scene_config(R"({"upright_prob": 1.5})", "s.json"),
                      Contains("upright_prob must be in [0, 1], got 1.5"));
    CHECK(parse_scene_config(scene_config_to_json(cfg), "round trip").upright_prob == 0.0);
    cfg.upright_prob = 0.25;
    CHECK(parse_scene_config(scene_config_to_json(cfg), "round trip").upright_prob == 0.25);
}

TEST_CASE("resting mode settings are validated", "[data][scene]") {
    CHECK_THROWS_WITH(parse_scene_config(R"({"pose_mode": "floating"})", "s.json"),
                      Contains("pose_mode") && Contains("floating"));
    CHECK_THROWS_WITH(parse_scene_config(R"({"camera_elevation": [0, 40]})", "s.json"),
                      Contains("camera_elevation"));
    CHECK_THROWS_WITH(parse_scene_config(R"({"camera_distance": [900, 600]})", "s.json"),
                      Contains("camera_distance"));
    CHECK_THROWS_WITH(parse_scene_config(R"({"camera_distance": [600]})", "s.json"),
                      Contains("camera_distance") && Contains("2 numbers"));
    CHECK_THROWS_WITH(parse_scene_config(R"({"table_size_mm": -1})", "s.json"),
                      Contains("table_size_mm"));
    const SceneConfig c = parse_scene_config(
        R"({"pose_mode": "resting", "camera_distance": [400, 800], "camera_roll_max": 5})", "s.json");
    CHECK(c.pose_mode == "resting");
    CHECK(c.camera_distance[1] == 800);
    const SceneConfig back = parse_scene_config(scene_config_to_json(c), "round trip");
    CHECK(back.pose_mode == "resting");
    CHECK(back.camera_roll_max == 5);
    CHECK(back.camera_distance[0] == 400);
}

namespace {

// The table's plane from the pixels with depth that show neither an object nor a distractor
// (blocks are distractors): its unit normal towards the camera and a point on it.
void fit_table(const RenderedFrame& f, Eigen::Vector3d* up, Eigen::Vector3d* mean) {
    const geom::Intrinsics& K = f.K;
    std::vector<Eigen::Vector3d> table;
    for (int v = 0; v < K.height; v += 3)
        for (int u = 0; u < K.width; u += 3) {
            const size_t i = size_t(v) * K.width + u;
            const double z = f.depth[i];
            if (z > 0 && f.mask[i] == 0 && f.distractor_mask[i] == 0)
                table.emplace_back((u + 0.5 - K.cx) * z / K.fx, (v + 0.5 - K.cy) * z / K.fy, z);
        }
    REQUIRE(table.size() > 100);
    *mean = Eigen::Vector3d::Zero();
    for (const auto& p : table) *mean += p;
    *mean /= double(table.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : table) cov += (p - *mean) * (p - *mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    *up = es.eigenvectors().col(0);
    if (up->dot(-*mean) < 0) *up = -*up;
}

// Height of the instance's lowest vertex above the table.
double lowest(const geom::Mesh& mesh, const RenderedInstance& gt, const Eigen::Vector3d& up,
              const Eigen::Vector3d& mean) {
    double lo = 1e9;
    for (int64_t v = 0; v < mesh.vertices.rows(); ++v)
        lo = std::min(lo, up.dot(gt.pose.R * mesh.vertices.row(v).cast<double>().transpose() +
                                 gt.pose.t - mean));
    return lo;
}

}  // namespace

TEST_CASE("resting mode: tallest poses, blocks to stand on, leaning objects", "[data][scene]") {
    Models m;
    auto mesh_of = [&](int id) { return id == 1 ? &m.a : id == 2 ? &m.b : &m.c; };
    SceneConfig cfg = small_config();
    cfg.pose_mode = "resting";
    cfg.noise.enabled = false;
    cfg.distractors_max = 0;
    cfg.targets_min = 3;
    cfg.camera_distance = {700, 900};
    RenderedFrame f;
    Eigen::Vector3d up, mean;
    SECTION("tall_prob 1: the 30 x 30 x 90 box stands on its small face in every frame") {
        cfg.tall_prob = 1;
        SceneGenerator gen(cfg, m.list());
        for (int64_t idx = 0; idx < 6; ++idx) {
            gen.render_frame(idx, f);
            fit_table(f, &up, &mean);
            for (const auto& gt : f.instances) {
                INFO("frame " << idx << " object " << gt.obj_id);
                CHECK(lowest(*mesh_of(gt.obj_id), gt, up, mean) == Approx(0.0).margin(1.5));
                if (gt.obj_id == 5) CHECK(std::fabs(up.dot(gt.pose.R.col(2))) == Approx(1.0).margin(1e-3));
            }
        }
    }
    SECTION("blocks with on_block_prob 1: every object rests on a block, >= 40 mm up") {
        cfg.blocks_min = cfg.blocks_max = 2;
        cfg.block_size_mm = {40, 120};
        cfg.on_block_prob = 1;
        SceneGenerator gen(cfg, m.list());
        for (int64_t idx = 0; idx < 6; ++idx) {
            gen.render_frame(idx, f);
            int64_t block_px = 0;
            for (uint8_t d : f.distractor_mask) block_px += d != 0;
            CHECK(block_px > 0);  // the blocks are rendered, as unannotated distractors
            // ... and marked in block_mask (no distractor here: the same pixels), never in
            // the instance mask.
            REQUIRE(f.block_mask.size() == f.mask.size());
            CHECK(f.block_mask == f.distractor_mask);
            for (size_t i = 0; i < f.mask.size(); ++i)
                if (f.block_mask[i]) REQUIRE(f.mask[i] == 0);
            fit_table(f, &up, &mean);
            for (const auto& gt : f.instances) {
                INFO("frame " << idx << " object " << gt.obj_id);
                const double lo = lowest(*mesh_of(gt.obj_id), gt, up, mean);
                CHECK(lo > 40 - 1.5);
                CHECK(lo < 120 + 1.5);
            }
        }
    }
    SECTION("block_lookalike_tol: block_mask marks only the blocks shaped like a target") {
        // ~60 mm cubes: within 20 % of the 70 mm sphere's box (|60 - 70| <= 14), not within
        // 10 % (> 7) of it nor of the 40 x 60 x 80 or 30 x 30 x 90 boxes.
        cfg.blocks_min = cfg.blocks_max = 2;
        cfg.block_size_mm = {59.5, 60.5};
        RenderedFrame all, none, alike;
        SceneGenerator(cfg, m.list()).render_frame(3, all);
        cfg.block_lookalike_tol = 0.1;
        SceneGenerator(cfg, m.list()).render_frame(3, none);
        cfg.block_lookalike_tol = 0.2;
        SceneGenerator(cfg, m.list()).render_frame(3, alike);
        int64_t block_px = 0;
        for (uint8_t d : all.block_mask) block_px += d != 0;
        REQUIRE(block_px > 0);
        // The same frame each time; only the marking differs.
        CHECK(none.depth == all.depth);
        CHECK(alike.depth == all.depth);
        CHECK(none.distractor_mask == all.distractor_mask);
        CHECK(alike.mask == all.mask);
        CHECK(std::count(none.block_mask.begin(), none.block_mask.end(), 255) == 0);
        CHECK(alike.block_mask == all.block_mask);
        CHECK(alike.block_mask == alike.distractor_mask);
    }
    SECTION("on_object_prob 1: every object after the first rests on one placed before it") {
        cfg.on_object_prob = 1;
        cfg.targets_min = cfg.targets_max = 2;
        SceneGenerator gen(cfg, m.list());
        for (int64_t idx = 0; idx < 6; ++idx) {
            gen.render_frame(idx, f);
            fit_table(f, &up, &mean);
            REQUIRE(f.instances.size() == 2);
            const RenderedInstance& a = f.instances[0];
            const RenderedInstance& b = f.instances[1];
            INFO("frame " << idx);
            CHECK(lowest(*mesh_of(a.obj_id), a, up, mean) == Approx(0.0).margin(1.5));
            // b is above the table by at least a third of a's smallest extent (30 mm boxes,
            // a 70 mm sphere: >= 10 mm), and above a's centre.
            CHECK(lowest(*mesh_of(b.obj_id), b, up, mean) > 10.0);
            CHECK(up.dot(b.pose.t - a.pose.t) > 0);
        }
    }
    SECTION("lean_prob 1: objects tilt off their stable faces and still touch the table") {
        cfg.lean_prob = 1;
        cfg.lean_max_deg = 30;
        SceneGenerator gen(cfg, m.list());
        int tilted = 0, boxes = 0;
        for (int64_t idx = 0; idx < 6; ++idx) {
            gen.render_frame(idx, f);
            fit_table(f, &up, &mean);
            for (const auto& gt : f.instances) {
                INFO("frame " << idx << " object " << gt.obj_id);
                CHECK(lowest(*mesh_of(gt.obj_id), gt, up, mean) == Approx(0.0).margin(1.5));
                if (gt.obj_id == 2) continue;
                double best = 0;
                for (int a = 0; a < 3; ++a) best = std::max(best, std::fabs(up.dot(gt.pose.R.col(a))));
                ++boxes;
                tilted += best < std::cos(2.0 * 3.14159265358979 / 180);
                CHECK(best >= std::cos(30.0 * 3.14159265358979 / 180) - 1e-6);
            }
        }
        CHECK(tilted >= boxes * 3 / 4);  // uniform tilts in [0, 30]: few below 2 degrees
    }
    SECTION("the settings are validated and round-trip") {
        CHECK_THROWS_WITH(parse_scene_config(R"({"tall_prob": 1.5})", "s.json"),
                          Contains("tall_prob must be in [0, 1], got 1.5"));
        CHECK_THROWS_WITH(parse_scene_config(R"({"lean_prob": -0.1})", "s.json"),
                          Contains("lean_prob must be in [0, 1]"));
        CHECK_THROWS_WITH(parse_scene_config(R"({"blocks_min": 3, "blocks_max": 2})", "s.json"),
                          Contains("blocks_min <= blocks_max"));
        CHECK_THROWS_WITH(parse_scene_config(R"({"block_size_mm": [90, 40]})", "s.json"),
                          Contains("block_size_mm must be [min, max]"));
        CHECK_THROWS_WITH(parse_scene_config(R"({"lean_max_deg": 120})", "s.json"),
                          Contains("lean_max_deg must be in [0, 90]"));
        CHECK_THROWS_WITH(parse_scene_config(R"({"blocks": 2})", "s.json"), Contains("unknown key 'blocks'"));
        cfg.tall_prob = 0.2, cfg.blocks_min = 1, cfg.blocks_max = 3, cfg.on_block_prob = 0.3;
        cfg.lean_prob = 0.4, cfg.lean_max_deg = 25, cfg.block_size_mm = {50, 150};
        const SceneConfig b = parse_scene_config(scene_config_to_json(cfg), "round trip");
        CHECK(b.tall_prob == 0.2);
        CHECK(b.blocks_min == 1);
        CHECK(b.blocks_max == 3);
        CHECK(b.on_block_prob == 0.3);
        CHECK(b.lean_prob == 0.4);
        CHECK(b.lean_max_deg == 25);
        CHECK(b.block_size_mm[1] == 150);
        cfg.on_object_prob = 0.15;
        CHECK(parse_scene_config(scene_config_to_json(cfg), "round trip").on_object_prob == 0.15);
        cfg.block_lookalike_tol = 0.25;
        CHECK(parse_scene_config(scene_config_to_json(cfg), "round trip").block_lookalike_tol ==
              0.25);
        CHECK_THROWS_WITH(parse_scene_config(R"({"block_lookalike_tol": 1.5})", "s.json"),
                          Contains("block_lookalike_tol must be in [0, 1], got 1.5"));
        CHECK_THROWS_WITH(parse_scene_config(R"({"on_object_prob": 2})", "s.json"),
                          Contains("on_object_prob must be in [0, 1], got 2"));
    }
}

TEST_CASE("scene bins: kinds_min/kinds_max draw copies of a few objects per frame",
          "[data][scene]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.pose_mode = "resting";
    cfg.unique_targets = false;
    cfg.kinds_min = cfg.kinds_max = 1;
    cfg.targets_min = cfg.targets_max = 4;
    cfg.distractors_min = cfg.distractors_max = 0;
    cfg.noise.enabled = false;
    RenderedFrame f;
    std::vector<int> kinds_seen;
    SceneGenerator gen(cfg, m.list());
    for (int64_t idx = 0; idx < 4; ++idx) {
        gen.render_frame(idx, f);
        REQUIRE(f.instances.size() == 4);  // four copies of one object
        for (const auto& inst : f.instances) CHECK(inst.obj_id == f.instances[0].obj_id);
        kinds_seen.push_back(f.instances[0].obj_id);
    }
    // Two kinds at most: never a third object in a frame.
    cfg.kinds_max = 2;
    cfg.targets_min = cfg.targets_max = 6;
    SceneGenerator gen2(cfg, m.list());
    for (int64_t idx = 0; idx < 4; ++idx) {
        gen2.render_frame(idx, f);
        std::vector<int> ids;
        for (const auto& inst : f.instances) ids.push_back(inst.obj_id);
        std::sort(ids.begin(), ids.end());
        ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
        CHECK(ids.size() <= 2);
        CHECK(f.instances.size() == 6);
    }
    // The key list: kinds need copies (unique_targets false) and a sane range.
    SceneConfig bad = cfg;
    bad.unique_targets = true;
    CHECK_THROWS_WITH(validate(bad), Contains("unique_targets false"));
    bad = cfg;
    bad.kinds_min = 3;
    CHECK_THROWS_WITH(validate(bad), Contains("kinds_min <= kinds_max"));
    bad = cfg;
    bad.kinds_min = 0;
    CHECK_THROWS_WITH(validate(bad), Contains("kinds_min >= 1"));
}

TEST_CASE("scene bins: configs/scenes/ycbv_bin.json reads and round-trips", "[data][scene]") {
    const SceneConfig c =
        load_scene_config(std::string(G2L_SOURCE_DIR) + "/configs/scenes/ycbv_bin.json");
    CHECK(c.kinds_min == 1);
    CHECK(c.kinds_max == 3);
    CHECK_FALSE(c.unique_targets);
    const SceneConfig back = parse_scene_config(scene_config_to_json(c), "round trip");
    CHECK(back.kinds_min == c.kinds_min);
    CHECK(back.kinds_max == c.kinds_max);
}

TEST_CASE("mesh_file_ids: BOP names keep their ids, other names take the smallest free ones, "
          "clashes are named", "[data]") {
    CHECK(mesh_file_ids({"/m/obj_000005.ply", "/m/bracket.ply", "/m/obj_000001.obj",
                         "/m/Housing v2.OBJ", "/m/obj_12.ply"}) ==
          std::vector<int>{5, 2, 1, 3, 12});
    CHECK(mesh_file_ids({"a.ply", "b.ply"}) == std::vector<int>{1, 2});
    CHECK(mesh_file_ids({}).empty());
    // Not BOP names: no digits, letters after them, a prefix.
    CHECK(mesh_file_ids({"obj_.ply", "obj_12a.ply", "myobj_000003.ply"}) ==
          std::vector<int>{1, 2, 3});
    REQUIRE_THROWS_WITH(mesh_file_ids({"x/obj_000008.ply", "y/obj_000008.obj"}),
                        Contains("'x/obj_000008.ply' and 'y/obj_000008.obj' both give object 8"));
    const std::string root = testing::temp_dir("obj_names");
    write_obj_names(root, {{1, "bracket"}, {14, "Housing v2"}});
    CHECK(testing::read_file(root + "/obj_names.json") ==
          "{\n  \"1\": \"bracket\",\n  \"14\": \"Housing v2\"\n}\n");
    REQUIRE_THROWS_WITH(write_obj_names(root + "/no/such/dir", {{1, "a"}}), Contains("obj_names.json"));
}

TEST_CASE("BopSceneWriter::resume: an interrupted render continues to the scene an "
          "uninterrupted one writes, without orphan images", "[data][scene][bop]") {
    Models m;
    SceneConfig cfg = small_config();
    cfg.target_obj_ids = {1, 5};
    SceneGenerator gen(cfg, m.list());
    const fs::path a = fs::path(testing::temp_dir("resume_a")) / "000000";
    const fs::path b = fs::path(testing::temp_dir("resume_b")) / "000000";
    RenderedFrame f;
    {  // uninterrupted
        BopSceneWriter w(a.string(), 4);
        for (int i = 0; i < 4; ++i) gen.render_frame(i, f), w.write(i, f);
        w.finish();
    }
    {  // killed after frame 2 was written, with frames 0-1 flushed (plus a temporary file)
        BopSceneWriter w(b.string(), 4);
        for (int i = 0; i < 2; ++i) gen.render_frame(i, f), w.write(i, f);
        w.flush();
        gen.render_frame(2, f), w.write(2, f);
        std::ofstream((b / "rgb" / "000003.png.tmp.99").string()) << "partial";
    }
    REQUIRE(fs::exists(b / "rgb" / "000002.png"));
    {
        BopSceneWriter w = BopSceneWriter::resume(b.string());
        CHECK(w.next_image_id() == 2);
        CHECK(w.planned() == 4);
        CHECK_FALSE(fs::exists(b / "rgb" / "000002.png"));  // the orphan of the unlisted frame
        CHECK_FALSE(fs::exists(b / "mask" / "000002_000000.png"));
        CHECK_FALSE(fs::exists(b / "rgb" / "000003.png.tmp.99"));
        CHECK(fs::exists(b / "rgb" / "000001.png"));
        CHECK(w.image_bytes(1) > 1000);
        for (int i = w.next_image_id(); i < 4; ++i) gen.render_frame(i, f), w.write(i, f);
        w.finish();
    }
    for (const char* file : {"scene_gt.json", "scene_camera.json", "scene_gt_info.json",
                             "rgb/000003.png", "depth/000002.png", "mask_visib/000003_000001.png"})
        CHECK(testing::read_file((a / file).string()) == testing::read_file((b / file).string()));
    CHECK(testing::dir_entries((a / "mask").string()) == testing::dir_entries((b / "mask").string()));
    CHECK_FALSE(fs::exists(b / kIncompleteMarker));
    // A complete scene, or none, has nothing to resume; a mangled record is named.
    REQUIRE_THROWS_WITH(BopSceneWriter::resume(b.string()), Contains("nothing to resume"));
    {
        BopSceneWriter w(b.string() + "_x", 2);
        std::ofstream(b.string() + "_x/scene_gt.json") << "{\"one\": []}";
    }
    REQUIRE_THROWS_WITH(BopSceneWriter::resume(b.string() + "_x"),
                        Contains("scene_gt.json") && Contains("'one' is not an image id"));
}
