// SPDX-License-Identifier: MIT
// The depth refinement on real frames (../shared/data/ycbv train_real, GT boxes, the shipped
// pose model): the refined pose never fits the object's measured points worse than the
// networks' pose did, by the fit the refinement minimises (mean capped point-to-model distance,
// geometry/refine.h fit_error, cap = inlier_frac x diameter), and over all instances it fits
// them much better.
#include <catch2/catch.hpp>

#include <cstdio>

#include "data/bop.h"
#include "geometry/refine.h"
#include "infer/frame_pipeline.h"
#include "nn/models/g2l_io.h"
#include "testing.h"

using namespace g2l;

// [slow]: 260 refinements, minutes under the sanitizers, whose run leaves [slow] out (the
// refinement runs there on the fixture frames and on rendered views).
TEST_CASE("refinement on the real YCB-V frames: never a worse fit than the networks' pose",
          "[infer][refine][shared][slow]") {
    const auto shared = testing::shared_data_dir();
    if (!shared) return testing::skip_without_shared_data("refinement on real YCB-V frames");
    const data::Dataset ds = data::open_bop(*shared + "/ycbv", "train_real", {});
    REQUIRE(ds.frames().size() == 60);
    nn::LoadedModel m = nn::load_model(std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l");
    PipelineOptions none_opt, turns_opt;
    none_opt.refine = Refinement::none;
    turns_opt.refine = Refinement::turns;
    infer::FramePipeline plain(infer::PipelineModel::of(m), none_opt);
    infer::FramePipeline refined(infer::PipelineModel::of(m), turns_opt);
    for (const auto& [id, om] : ds.models()) refined.add_mesh(id, ds.load_model_mesh(id), om.info);
    const geom::RefineOptions ro;  // what the pipeline refines with

    int n = 0, better = 0;
    double sum_net = 0, sum_ref = 0, worst = -1e9;
    for (const auto& f : ds.frames()) {
        int w = 0, h = 0;
        const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
        std::vector<infer::PoseRequest> req;
        for (const auto& gi : f.instances) {
            infer::PoseRequest r;
            r.obj_id = gi.obj_id;
            r.box = {gi.box().x, gi.box().y, gi.box().w, gi.box().h};
            req.push_back(r);
        }
        std::vector<infer::PoseOutcome> a, b;
        plain.run(depth.data(), f.K, req, &a);
        refined.run(depth.data(), f.K, req, &b);
        REQUIRE(a.size() == b.size());
        for (size_t i = 0; i < a.size(); ++i) {
            INFO("frame " << f.image_id << " object " << a[i].obj_id);
            REQUIRE(a[i].ok() == b[i].ok());
            if (!a[i].ok()) continue;
            // The same crop and segmentation: the refinement saw the points the networks did.
            REQUIRE(a[i].object_rows == b[i].object_rows);
            REQUIRE(b[i].refined);
            const infer::PreparedMesh* pm = refined.mesh(a[i].obj_id);
            REQUIRE(pm != nullptr);
            geom::Points obs(int64_t(a[i].object_rows.size()), 3);
            for (size_t k = 0; k < a[i].object_rows.size(); ++k)
                obs.row(int64_t(k)) = a[i].crop.row(a[i].object_rows[k]);
            const double cap = ro.inlier_frac * pm->info.diameter;
            const double fit_net = geom::fit_error(*pm->tree, obs, a[i].pose, cap);
            const double fit_ref = geom::fit_error(*pm->tree, obs, b[i].pose, cap);
            INFO("fit " << fit_net << " -> " << fit_ref << " mm (cap " << cap << ")");
            // Never worse, by more than the ICP's grid rounding (ClosestPointGrid: cells of
            // diameter / 80, the finalists polished on the exact tree) — in mm.
            CHECK(fit_ref <= fit_net + 0.05);
            worst = std::max(worst, fit_ref - fit_net);
            better += fit_ref < fit_net;
            sum_net += fit_net;
            sum_ref += fit_ref;
            ++n;
        }
    }
    std::printf("refinement on %d real instances: mean fit %.2f -> %.2f mm, better on %d, worst "
                "change %+.3f mm\n", n, sum_net / n, sum_ref / n, better, worst);
    REQUIRE(n >= 250);  // 260 GT instances; a handful may have too few points
    // Measured 2026-12-04: 260 instances, mean fit 9.63 -> 3.10 mm, better on all 260 (the
    // smallest gain 0.94 mm). Pinned at the measured mean + 0.5 mm and every instance better.
    CHECK(sum_ref / n < 3.10 + 0.5);
    CHECK(sum_net / n > 2 * sum_ref / n);
    CHECK(better == n);
}
