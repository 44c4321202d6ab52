// SPDX-License-Identifier: MIT
// The rotation blocks learn (issue: "the rotation must learn"): one object of the shipped fixtures,
// noise-free resting-pose renders, blocks A and B alone on ground-truth object points, fixed
// seed. The keypoint error must fall below 10% of the diameter — the "predict zero" plateau sits
// at ~0.6 — while the official millimetre unit with all lr multipliers at 1 stays on that
// plateau (what held the rotation before). Learning curves on held-out renders, with every
// factor, are in docs/experiments.md (g2l_rotstudy).
#include <catch2/catch.hpp>
#include <map>

#include "data/bop.h"
#include "data/scene.h"
#include "geometry/keypoints.h"
#include "geometry/symmetry.h"
#include "testing.h"
#include "tools/rot_study.h"
#include "train/sources.h"

using namespace g2l;

namespace {

struct Setup {
    data::Dataset ds;
    std::map<int, train::SampleModel> models;
    std::unique_ptr<train::SampleMaker> maker;
    train::KeypointTable kps;
    train::SymmetricKeypoints sym;
    std::vector<double> diam;
    std::vector<train::PoseSample> pool, val;
};

// Renders `n_train` + `n_val` samples of object `id` resting on a table (noise-free).
std::unique_ptr<Setup> make_setup(int id, int n_train, int n_val) {
    auto s = std::make_unique<Setup>();
    data::BopOptions bo;
    bo.obj_ids = {id};
    s->ds = data::open_bop_models(testing::fixture_dir() + "/ycbv_drill", bo);
    const geom::Mesh& mesh = s->ds.load_model_mesh(id);
    s->models[id] = {&mesh, s->ds.models().at(id).info};
    train::SampleConfig sc;
    sc.points = 512;
    sc.augment = false;
    sc.center_jitter_mm = 0;
    sc.box_jitter_frac = 0;
    s->maker = std::make_unique<train::SampleMaker>(sc, s->models, std::map<int, int>{{id, 0}});
    const geom::Points kp = geom::keypoints(mesh, s->ds.models().at(id).info, "bbx8");
    s->kps.resize(1);
    for (int64_t k = 0; k < kp.rows(); ++k) s->kps[0].push_back(kp.row(k).transpose());
    s->sym.resize(1);
    for (const auto& t : geom::geometric_symmetries(s->maker->tree(id), s->maker->info(id))) {
        std::vector<Eigen::Vector3f> set;
        for (const auto& p : s->kps[0]) set.push_back(t.R * p + t.t);
        s->sym[0].push_back(set);
    }
    s->diam.push_back(s->ds.models().at(id).info.diameter);
    data::SceneConfig scene = data::parse_scene_config(
        R"({"pose_mode": "resting", "targets_min": 1, "targets_max": 1, "distractors_max": 0,
            "camera_distance": [500, 900], "noise": {"enabled": false}, "seed": 21})",
        "test scene");
    const std::vector<data::SceneModel> sm{{id, &mesh}};
    train::SyntheticSource src(scene, sm, *s->maker, 100000, 0);
    for (int64_t i = 0; int(s->pool.size() + s->val.size()) < n_train + n_val && i < 4 * (n_train + n_val); ++i) {
        Rng r(uint64_t(i) + 1);
        train::PoseSample p;
        if (!src.get(i, r, &p)) continue;
        (int(s->pool.size()) < n_train ? s->pool : s->val).push_back(std::move(p));
    }
    REQUIRE(int(s->pool.size()) == n_train);
    REQUIRE(int(s->val.size()) == n_val);
    REQUIRE(s->sym[0].size() == 1);  // the drill has no geometric symmetry
    return s;
}

}  // namespace

TEST_CASE("rotation blocks learn: keypoint error below 10% of the diameter",
          "[train][rotation][slow]") {
    // 035_power_drill (tests/data/ycbv_drill): no geometric symmetry, so depth alone tells its
    // pose. 64 noise-free renders resting on a table, blocks A and B on the GT object points.
    auto s = make_setup(15, 64, 0);
    tools::RotStudyConfig c;
    c.steps = 200;
    c.batch = 32;
    c.lr = 2e-3;
    c.points = 128;
    c.eval_every = 200;
    c.width = 0.25;
    c.dropout = 0;
    c.seed = 3;
    size_t next = 0;
    const tools::SampleDraw draw = [&](int64_t, train::PoseSample* out) {
        *out = s->pool[next++ % s->pool.size()];
        return true;
    };
    // Error on the rendered views it trained on (eval mode, deterministic point picks).
    const auto fit = tools::rot_study(c, 1, s->kps, s->diam, &s->sym, draw, s->pool);
    REQUIRE(fit.size() == 1);
    INFO("keypoint error " << fit.back().val_kp_err_mm << " mm = " << fit.back().val_kp_err_frac
                           << " of the diameter, median rotation error "
                           << fit.back().val_rot_err_deg_median << " deg");
    CHECK(fit.back().val_kp_err_frac < 0.10);
    CHECK(fit.back().val_rot_err_deg_median < 10.0);

    // What held the rotation before: the official unit (mm) with every lr multiplier at 1
    // stays on the "predict zero" plateau (error ~ the keypoints' own size, ~0.6 of the
    // diameter) over the first half of that budget.
    c.rot_unit = "mm";
    c.steps = c.eval_every = 100;
    next = 0;
    const auto flat = tools::rot_study(c, 1, s->kps, s->diam, &s->sym, draw, s->pool);
    INFO("mm unit: " << flat.back().val_kp_err_frac << " of the diameter");
    CHECK(flat.back().val_kp_err_frac > 0.45);
}

TEST_CASE("rot_study: bad settings throw", "[train][rotation]") {
    tools::RotStudyConfig c;
    const train::KeypointTable kps(1, std::vector<Eigen::Vector3f>(8, Eigen::Vector3f(1, 2, 3)));
    const tools::SampleDraw never = [](int64_t, train::PoseSample*) { return false; };
    CHECK_THROWS_WITH(tools::rot_study(c, 1, kps, {100.0}, nullptr, never, {}),
                      Catch::Contains("empty validation set"));
    std::vector<train::PoseSample> val(1);
    CHECK_THROWS_WITH(tools::rot_study(c, 1, kps, {}, nullptr, never, val),
                      Catch::Contains("diameters"));
    c.symmetric = true;
    CHECK_THROWS_WITH(tools::rot_study(c, 1, kps, {100.0}, nullptr, never, val),
                      Catch::Contains("symmetry tables"));
    const train::SymmetricKeypoints one_table(1, kps);
    c.lr_decay_factor = 0;
    CHECK_THROWS_WITH(tools::rot_study(c, 1, kps, {100.0}, &one_table, never, val),
                      Catch::Contains("lr_decay_factor in (0, 1], got 0 and 0"));
    c.lr_decay_factor = 0.5;
    c.symmetric = false;
    c.steps = 0;
    CHECK_THROWS_WITH(tools::rot_study(c, 1, kps, {100.0}, nullptr, never, val),
                      Catch::Contains("must be > 0"));
    c.steps = 1;
    CHECK_THROWS_WITH(tools::rot_study(c, 1, kps, {100.0}, nullptr, never, val),
                      Catch::Contains("unusable draws"));
}
