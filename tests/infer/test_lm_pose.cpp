// SPDX-License-Identifier: MIT
// The shipped one-model-for-8-objects LINEMOD-like pose model (models/lm_pose.g2l, issue 26)
// on unseen renders of configs/scenes/lm.json (../shared/data/lmo meshes), GT boxes: the
// networks alone and with the default refinement, pinned near the values measured when it
// was shipped (docs/results.md has the full 240-instance figures).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdio>

#include "data/bop.h"
#include "data/scene.h"
#include "geometry/metrics.h"
#include "geometry/symmetry.h"
#include "infer/frame_pipeline.h"
#include "nn/models/g2l_io.h"
#include "testing.h"

using namespace g2l;

namespace {

// Measured when models/lm_pose.g2l was shipped (the test's printed line).
constexpr double PIN_NETS_ACC = 92.5, PIN_NETS_ROT = 8.8, PIN_REFINED_ACC = 95.0, PIN_REFINED_ROT = 0.7;

struct Figures {
    int n = 0, ok = 0;
    double median_rot = 0;
};

}  // namespace

// [slow]: ~10 s in Release, minutes under the sanitizers, whose run leaves [slow] out (the same
// pipeline runs there on the fixture frames).
TEST_CASE("the shipped LM-O pose model on unseen LINEMOD-like renders, pinned",
          "[infer][shared][lm][slow]") {
    const auto shared = testing::shared_data_dir();
    if (!shared) return testing::skip_without_shared_data("the LM-O pose model on renders");
    const data::Dataset ds = data::open_bop_models(*shared + "/lmo");
    REQUIRE(ds.models().size() == 8);
    data::SceneConfig sc =
        data::load_scene_config(std::string(G2L_SOURCE_DIR) + "/configs/scenes/lm.json");
    sc.seed = 31337;  // the held-out seed of docs/results.md (training mixes 2026 with the epoch)
    std::vector<data::SceneModel> models;
    for (const auto& [id, om] : ds.models()) models.push_back({id, &ds.load_model_mesh(id)});
    data::SceneGenerator gen(sc, models);

    nn::LoadedModel m = nn::load_model(std::string(G2L_SOURCE_DIR) + "/models/lm_pose.g2l");
    REQUIRE(m.class_of.size() == 8);
    PipelineOptions none_opt, turns_opt;
    none_opt.refine = Refinement::none;
    turns_opt.refine = Refinement::turns;
    infer::FramePipeline nets(infer::PipelineModel::of(m), none_opt);
    infer::FramePipeline refined(infer::PipelineModel::of(m), turns_opt);
    std::map<int, geom::Points> pts;
    std::map<int, std::vector<geom::SymmetryTransform>> syms;
    for (const auto& [id, om] : ds.models()) {
        const geom::Mesh& mesh = ds.load_model_mesh(id);
        refined.add_mesh(id, mesh, om.info);
        const int64_t nv = mesh.vertices.rows(), keep = std::min<int64_t>(nv, 2000);
        pts[id].resize(keep, 3);
        for (int64_t i = 0; i < keep; ++i) pts[id].row(i) = mesh.vertices.row(i * nv / keep);
        syms[id] = geom::geometric_symmetries(*refined.mesh(id)->tree, om.info);
    }

    Figures a, b;
    std::vector<double> rot_a, rot_b;
    data::RenderedFrame fr;
    for (int64_t k = 0; k < 40; ++k) {
        gen.render_frame(k, fr, 0);
        std::vector<infer::PoseRequest> req;
        std::vector<const data::RenderedInstance*> gt;
        for (const auto& ri : fr.instances) {
            if (ri.bbox_visib.empty() || ri.visib_fract < 0.1) continue;
            infer::PoseRequest r;
            r.obj_id = ri.obj_id;
            r.box = ri.bbox_visib;
            req.push_back(r);
            gt.push_back(&ri);
        }
        std::vector<infer::PoseOutcome> oa, ob;
        nets.run(fr.depth.data(), fr.K, req, &oa);
        refined.run(fr.depth.data(), fr.K, req, &ob);
        for (size_t i = 0; i < req.size(); ++i) {
            const int id = gt[i]->obj_id;
            const auto& om = ds.model(id);
            // ADD(-S) < 0.1 d: ADD-S for the eggbox and the glue, ADD for the others.
            auto score = [&](const infer::PoseOutcome& o, Figures* fig, std::vector<double>* rot) {
                ++fig->n;
                if (!o.ok()) {
                    rot->push_back(180);
                    return;
                }
                const double e = om.info.symmetric ? geom::adds(o.pose, gt[i]->pose, pts[id])
                                                   : geom::add(o.pose, gt[i]->pose, pts[id]);
                fig->ok += e < 0.1 * om.info.diameter;
                rot->push_back(geom::rotation_error_sym_deg(o.pose.R, gt[i]->pose.R, syms[id]));
            };
            score(oa[i], &a, &rot_a);
            score(ob[i], &b, &rot_b);
        }
    }
    auto median = [](std::vector<double> v) {
        std::sort(v.begin(), v.end());
        return v[v.size() / 2];
    };
    a.median_rot = median(rot_a);
    b.median_rot = median(rot_b);
    const double acc_a = 100.0 * a.ok / a.n, acc_b = 100.0 * b.ok / b.n;
    std::printf("models/lm_pose.g2l on %d unseen renders: networks alone ADD(-S) %.1f %%, rotation "
                "median %.1f deg; refined %.1f %%, %.1f deg\n", a.n, acc_a, a.median_rot, acc_b,
                b.median_rot);
    REQUIRE(a.n >= 35);
    // Measured 2026-12-04 (the printed line): pinned at the measured value minus 5 points
    // (accuracy) and plus 3 degrees (rotation).
    CHECK(acc_a >= PIN_NETS_ACC - 5);
    CHECK(a.median_rot <= PIN_NETS_ROT + 3);
    CHECK(acc_b >= PIN_REFINED_ACC - 5);
    CHECK(b.median_rot <= PIN_REFINED_ROT + 3);
}
