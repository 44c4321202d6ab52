// SPDX-License-Identifier: MIT
// g2l_train end to end on tiny settings: losses fall, resume == uninterrupted (bitwise), the
// checkpoint describes the model, g2l_eval's evaluation runs on real frames.
#include <catch2/catch.hpp>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/checkpoint.h"
#include "testing.h"
#include "nn/models/g2l_io.h"
#include "train/config.h"
#include "eval/evaluate.h"
#include "train/model_io.h"
#include "train/trainer.h"
#include "data/bop.h"

using namespace g2l;
namespace fs = std::filesystem;

namespace {

std::string tiny_config(const std::string& run_dir, int epochs, int64_t samples_per_epoch,
                        int frames = 16) {
    const std::string mini = testing::fixture_dir() + "/ycbv_mini";
    nlohmann::json j = {
        {"name", "tiny"}, {"seed", 3}, {"threads", 2}, {"run_dir", run_dir},
        {"data",
         {{"object_ids", {8, 14}},
          {"train", {{{"type", "synthetic"}, {"models_root", mini}, {"frames", frames},
                      {"scene", {{"targets_min", 1}, {"targets_max", 2}, {"distractors_max", 0},
                                 {"z_min", 500}, {"z_max", 800}, {"xy_frac", 0.5},
                                 {"seed", 5}}}}}},
          {"val", {{{"type", "bop"}, {"root", mini}, {"split", "train_real"}}}}}},
        {"sampling", {{"points", 128}, {"seg_points", 64}, {"min_points", 30}}},
        {"model", {{"num_classes", 2}, {"width", 0.125}}},
        {"schedule", {{"kind", "constant"}}},
        {"train", {{"epochs", epochs}, {"batch", 4}, {"samples_per_epoch", samples_per_epoch},
                   {"checkpoint_every", 0}, {"val_every", 0}, {"log_every", 1}}}};
    return j.dump();
}

std::vector<double> logged(const std::string& run_dir, const char* key) {
    std::ifstream f(run_dir + "/steps.jsonl");
    std::vector<double> v;
    std::string line;
    while (std::getline(f, line)) {
        const auto j = nlohmann::json::parse(line);
        if (!j.contains("event")) v.push_back(j.at(key).get<double>());  // not a "stopped" record
    }
    return v;
}

// Every tensor of the two checkpoints is bitwise the same.
void require_same_checkpoint(const std::string& pa, const std::string& pb) {
    const Checkpoint ka = load_checkpoint(pa), kb = load_checkpoint(pb);
    REQUIRE(ka.tensors.size() == kb.tensors.size());
    for (const auto& [name, t] : ka.tensors) {
        INFO(name);
        REQUIRE(kb.tensors.count(name));
        const Tensor& u = kb.tensors.at(name);
        REQUIRE(u.shape() == t.shape());
        REQUIRE(std::memcmp(u.data(), t.data(), t.nbytes()) == 0);
    }
}

}  // namespace

TEST_CASE("g2l_train: a short run on synthetic renders lowers the losses", "[train][trainer]") {
    const std::string dir = testing::temp_dir("train_falls");
    const auto cfg = train::parse_config_text(tiny_config(dir, 1, 160, 100), "tiny.json");
    train::TrainOptions opt;
    opt.progress = false;
    const auto sum = train::run_training(cfg, opt);
    REQUIRE(sum.steps == 40);
    const auto loss = logged(dir, "loss"), seg = logged(dir, "seg"), vec = logged(dir, "vec"),
               acc = logged(dir, "seg_acc");
    REQUIRE(loss.size() == 40);
    auto mean = [](const std::vector<double>& v, size_t a, size_t b) {
        double s = 0;
        for (size_t i = a; i < b; ++i) s += v[i];
        return s / double(b - a);
    };
    INFO("seg " << mean(seg, 0, 8) << " -> " << mean(seg, 32, 40) << ", vec " << mean(vec, 0, 8)
                << " -> " << mean(vec, 32, 40) << ", seg acc " << mean(acc, 0, 8) << " -> "
                << mean(acc, 32, 40));
    // In 40 steps of a width-0.125 net the segmentation and the keypoint vectors (block A)
    // learn visibly; keypoint / translation regression in mm needs far longer runs.
    // Measured (2026-12-01): seg 0.51 -> 0.32 (x0.63), vec 0.49 -> 0.38 (x0.78).
    REQUIRE(mean(seg, 32, 40) < 0.72 * mean(seg, 0, 8));
    REQUIRE(mean(vec, 32, 40) < 0.9 * mean(vec, 0, 8));
    REQUIRE(mean(acc, 32, 40) > mean(acc, 0, 8) + 0.05);
    for (double l : loss) REQUIRE(std::isfinite(l));
    for (const char* f : {"config.json", "steps.jsonl", "epochs.jsonl", "last.g2l"})
        REQUIRE(fs::exists(fs::path(dir) / f));
}

TEST_CASE("g2l_train: a synthetic scene's distractors need no class", "[train][trainer]") {
    // One class (object 8); object 14 is only clutter (configs/lm_ablation.json: 2 classes,
    // the other six LM-O objects as distractors). Its mesh loads with the source's objects.
    const std::string dir = testing::temp_dir("train_distractors");
    auto j = nlohmann::json::parse(tiny_config(dir, 1, 8));
    j["data"]["object_ids"] = {8};
    j["model"]["num_classes"] = 1;
    j["data"]["train"][0]["objects"] = {8};
    j["data"]["train"][0]["scene"]["distractor_obj_ids"] = {14};
    j["data"]["train"][0]["scene"]["distractors_min"] = 1;
    j["data"]["train"][0]["scene"]["distractors_max"] = 1;
    j["data"]["val"][0]["objects"] = {8};
    train::TrainOptions opt;
    opt.progress = false;
    REQUIRE(train::run_training(train::parse_config_text(j.dump(), "d.json"), opt).steps == 2);
    for (const double l : logged(dir, "loss")) REQUIRE(std::isfinite(l));
    // A distractor that is not in the dataset is named.
    j["data"]["train"][0]["scene"]["distractor_obj_ids"] = {99};
    const std::string dir2 = testing::temp_dir("train_distractors_bad");
    j["run_dir"] = dir2;
    REQUIRE_THROWS_WITH(train::run_training(train::parse_config_text(j.dump(), "d.json"), opt),
                        Catch::Contains("99"));
}

TEST_CASE("g2l_train: stopping and resuming equals an uninterrupted run, bitwise",
          "[train][trainer][resume]") {
    const std::string a = testing::temp_dir("resume_a"), b = testing::temp_dir("resume_b");
    train::TrainOptions opt;
    opt.progress = false;
    // 2 epochs of 4 steps; stop B at step 3 (mid-epoch) and again at 5 (next epoch).
    const auto ca = train::parse_config_text(tiny_config(a, 2, 16), "a.json");
    const auto cb = train::parse_config_text(tiny_config(b, 2, 16), "b.json");
    REQUIRE(train::run_training(ca, opt).steps == 8);
    opt.max_steps = 3;
    REQUIRE(train::run_training(cb, opt).steps == 3);
    opt.resume_dir = b;
    opt.max_steps = 5;
    REQUIRE(train::run_training(cb, opt).steps == 5);
    opt.max_steps = 0;
    const auto sb = train::run_training(cb, opt);
    REQUIRE(sb.steps == 8);
    require_same_checkpoint(a + "/last.g2l", b + "/last.g2l");
    REQUIRE(logged(a, "loss") == logged(b, "loss"));
}

TEST_CASE("g2l_train: model.init starts from another run's weights with a fresh optimiser",
          "[train][trainer]") {
    const std::string a = testing::temp_dir("init_a"), b = testing::temp_dir("init_b"),
                      c = testing::temp_dir("init_c");
    train::TrainOptions opt;
    opt.progress = false;
    REQUIRE(train::run_training(train::parse_config_text(tiny_config(a, 1, 16), "a.json"), opt)
                .steps == 4);
    // B starts from A's weights, C from the random initialisation; both are stopped before
    // their first step, so their checkpoints hold the weights they started from.
    auto jb = nlohmann::json::parse(tiny_config(b, 1, 16));
    jb["model"]["init"] = a + "/last.g2l";
    const auto cb = train::parse_config_text(jb.dump(), "b.json");
    REQUIRE(cb.model.init == a + "/last.g2l");
    std::atomic<bool> stop{true};
    train::TrainOptions sig = opt;
    sig.stop_flag = &stop;
    REQUIRE(train::run_training(cb, sig).steps == 0);
    REQUIRE(train::run_training(train::parse_config_text(tiny_config(c, 1, 16), "c.json"), sig)
                .steps == 0);
    const auto wa = nn::load_model(a + "/last.g2l").net->state_dict();
    const auto wb = nn::load_model(b + "/last.g2l").net->state_dict();
    const auto wc = nn::load_model(c + "/last.g2l").net->state_dict();
    REQUIRE(wa.size() == wb.size());
    int differ_c = 0;
    for (const auto& [name, t] : wa) {
        INFO(name);
        REQUIRE(wb.count(name));
        REQUIRE(std::memcmp(wb.at(name).data(), t.data(), t.nbytes()) == 0);
        differ_c += std::memcmp(wc.at(name).data(), t.data(), t.nbytes()) != 0;
    }
    CHECK(differ_c > 0);  // 4 steps moved A's weights away from the initialisation
    // Started over (--force), B trains from A's weights with a fresh optimiser from step 0.
    opt.max_steps = 2;
    opt.force = true;
    REQUIRE(train::run_training(cb, opt).steps == 2);
    opt.force = false;
    // Another network or missing file: named before the run directory or the data are touched
    // (nothing is written there).
    const std::string d = testing::temp_dir("init_d");
    auto bad = nlohmann::json::parse(tiny_config(d, 1, 16));
    bad["model"]["init"] = a + "/last.g2l";
    bad["model"]["width"] = 0.25;
    REQUIRE_THROWS_WITH(train::run_training(train::parse_config_text(bad.dump(), "d.json"), opt),
                        Catch::Contains("model.init '" + a + "/last.g2l': its network") &&
                            Catch::Contains("width 0.125") && Catch::Contains("width 0.25"));
    CHECK(testing::dir_entries(d).empty());
    bad["run_dir"] = testing::temp_dir("init_e");
    bad["model"]["width"] = 0.125;
    bad["data"]["object_ids"] = {14, 8};
    REQUIRE_THROWS_WITH(train::run_training(train::parse_config_text(bad.dump(), "e.json"), opt),
                        Catch::Contains("its objects differ"));
    bad["run_dir"] = testing::temp_dir("init_f");
    bad["data"]["object_ids"] = {8, 14};
    bad["model"]["init"] = a + "/missing.g2l";
    REQUIRE_THROWS_WITH(train::run_training(train::parse_config_text(bad.dump(), "f.json"), opt),
                        Catch::Contains("missing.g2l"));
    CHECK(testing::dir_entries(bad["run_dir"].get<std::string>()).empty());
}

TEST_CASE("g2l_train: a signal while the batch is gathered stops at once and resumes, and a batch "
          "that cannot fit in memory is refused", "[train][trainer][resume]") {
    const std::string a = testing::temp_dir("sig_a"), b = testing::temp_dir("sig_b");
    train::TrainOptions opt;
    opt.progress = false;
    const auto ca = train::parse_config_text(tiny_config(a, 1, 16), "a.json");
    const auto cb = train::parse_config_text(tiny_config(b, 1, 16), "b.json");
    REQUIRE(train::run_training(ca, opt).steps == 4);
    // The flag is up before the first batch is complete: no step runs, last.g2l holds step 0
    // and the log says why; the resumed run is the uninterrupted one.
    std::atomic<bool> stop{true};
    train::TrainOptions sig = opt;
    sig.stop_flag = &stop;
    const auto sb = train::run_training(cb, sig);
    REQUIRE(sb.interrupted);
    REQUIRE(sb.stopped_early);
    REQUIRE(sb.steps == 0);
    REQUIRE(fs::exists(b + "/last.g2l"));
    std::ifstream log(b + "/steps.jsonl");
    std::string last, line;
    while (std::getline(log, line)) last = line;
    const auto rec = nlohmann::json::parse(last);
    REQUIRE(rec.at("event") == "stopped");
    REQUIRE(rec.at("reason") == "signal");
    REQUIRE(rec.at("step") == 0);
    train::TrainOptions resume = opt;
    resume.resume_dir = b;
    REQUIRE(train::run_training(cb, resume).steps == 4);
    require_same_checkpoint(a + "/last.g2l", b + "/last.g2l");
    REQUIRE(logged(a, "loss") == logged(b, "loss"));
    // batch 10^7 at 128 points, width 0.125: ~1.6 TB; refused before the run directory exists.
    const std::string c = testing::temp_dir("sig_c") + "/run";
    auto big = nlohmann::json::parse(tiny_config(c, 1, 16));
    big["train"]["batch"] = 10000000;
    REQUIRE_THROWS_WITH(train::run_training(train::parse_config_text(big.dump(), "big.json"), opt),
                        Catch::Contains("train.batch 10000000: a training step needs about") &&
                            Catch::Contains("GB available: lower train.batch"));
    REQUIRE(!fs::exists(c));
}

TEST_CASE("g2l_train: making the next batch on a second thread changes nothing, bitwise",
          "[train][trainer]") {
    const std::string a = testing::temp_dir("prefetch_on"), b = testing::temp_dir("prefetch_off");
    train::TrainOptions opt;
    opt.progress = false;
    auto ca = train::parse_config_text(tiny_config(a, 2, 16), "a.json");
    auto cb = train::parse_config_text(tiny_config(b, 2, 16), "b.json");
    REQUIRE(ca.train.prefetch);  // the default
    cb.train.prefetch = false;
    REQUIRE(train::run_training(ca, opt).steps == 8);
    REQUIRE(train::run_training(cb, opt).steps == 8);
    require_same_checkpoint(a + "/last.g2l", b + "/last.g2l");
    REQUIRE(logged(a, "loss") == logged(b, "loss"));
    REQUIRE(logged(a, "loss").size() == 8);
}

TEST_CASE("g2l_train: 1 and 2 threads give bitwise identical checkpoints", "[train][trainer]") {
#ifndef _OPENMP
    testing::mark_skipped("built without OpenMP: one thread count only");
    return;
#else
    const std::string a = testing::temp_dir("threads1"), b = testing::temp_dir("threads2");
    train::TrainOptions opt;
    opt.progress = false;
    auto ca = train::parse_config_text(tiny_config(a, 1, 16), "a.json");
    auto cb = train::parse_config_text(tiny_config(b, 1, 16), "b.json");
    ca.threads = 1;
    cb.threads = 2;
    REQUIRE(train::run_training(ca, opt).steps == 4);
    REQUIRE(train::run_training(cb, opt).steps == 4);
    require_same_checkpoint(a + "/last.g2l", b + "/last.g2l");
    REQUIRE(logged(a, "loss") == logged(b, "loss"));
#endif
}

TEST_CASE("g2l_eval: a checkpoint alone rebuilds the model, evaluation on real frames",
          "[train][eval]") {
    const std::string dir = testing::temp_dir("eval");
    const auto cfg = train::parse_config_text(tiny_config(dir, 1, 8), "e.json");
    train::TrainOptions opt;
    opt.progress = false;
    train::run_training(cfg, opt);
    train::LoadedModel m = train::load_model(dir + "/last.g2l");
    REQUIRE(m.class_of == std::map<int, int>{{8, 0}, {14, 1}});
    REQUIRE(m.keypoints.size() == 2);
    REQUIRE(m.keypoints[0].size() == 8);
    data::BopOptions o;
    o.obj_ids = {8, 14};
    const auto ds = data::open_bop(testing::fixture_dir() + "/ycbv_mini", "train_real", o);
    eval::EvalOptions eo;
    eo.pipeline.refine = Refinement::none;  // the networks' poses, as validation scores them
    const auto r = eval::evaluate_gt_boxes(infer::PipelineModel::of(m), ds, eo);
    REQUIRE(r.instances == 4);
    REQUIRE(r.objects.size() == 2);
    for (const auto& s : r.objects) {
        std::printf("tiny model: object %d auc_adds %.3f auc_add %.3f rot_err_sym_median %.3f\n",
                    s.obj_id, s.auc_adds, s.auc_add, s.rot_err_sym_deg_median);
        REQUIRE(s.count == 2);
        REQUIRE(s.auc_add <= s.auc_adds + 1e-9);  // ADD >= ADD-S per instance
        // Pinned near the values measured 2026-12-04 (printed above): ADD-S AUC 93.5 (object
        // 8) and 90.6 (object 14) +- 5 (the same in the portable -O1 sanitizer build). The
        // 8-step model's rotation is untrained, a random angle: 103 / 146 deg in the native
        // Release build, 173 deg for object 14 in the portable -O1 build (other rounding, other
        // random model), so it is not pinned here; the shipped, trained models' rotations are
        // (tests/infer/test_lm_pose.cpp, test_pose_estimator.cpp, tools/test_install.sh).
        CHECK(s.auc_adds == Approx(s.obj_id == 8 ? 93.5 : 90.6).epsilon(0).margin(5.0));
    }
    const std::string md = eval::report_markdown(r);
    REQUIRE_THAT(md, Catch::Contains("009_gelatin_box") && Catch::Contains("**average**"));
    // a truncated checkpoint is reported with its file name
    const std::string cut = dir + "/cut.g2l";
    fs::copy_file(dir + "/last.g2l", cut);
    fs::resize_file(cut, fs::file_size(cut) / 2);
    REQUIRE_THROWS_WITH(train::load_model(cut), Catch::Contains("cut.g2l"));
    REQUIRE_THROWS_WITH(train::load_model(dir + "/missing.g2l"), Catch::Contains("missing.g2l"));

    // The figures modulo symmetries are percentages / degrees, and ADD-sym <= ADD accuracy.
    for (const auto& s : r.objects) {
        CHECK(s.acc_addsym_10 >= s.acc_add_s_10 - 1e-9 * double(!s.symmetric));
        CHECK(s.acc_adds_all_10 >= s.acc_addsym_10 - 1e-9);  // ADD-S <= ADD-sym per instance
        CHECK(s.num_symmetries >= 1);
    }
    CHECK_THAT(eval::report_json(r), Catch::Contains("acc_addsym_10") &&
                                          Catch::Contains("rot_err_sym_deg_median") &&
                                          Catch::Contains("acc_adds_all_10") &&
                                          Catch::Contains("\"oracle\": \"none\""));

    // The seg IoU against training's label rule is a fraction; with the ground-truth object
    // points (oracle seg) it is 1; with the GT translation too the translation error is 0 and
    // the errors are the rotation's alone.
    std::vector<eval::InstanceResult> plain, oracle;
    eval::evaluate_instances(infer::PipelineModel::of(m), ds, eo, &plain);
    eval::EvalOptions eo2 = eo;
    eo2.oracle_seg = true;
    eo2.oracle_t = true;
    const auto ro = eval::evaluate_instances(infer::PipelineModel::of(m), ds, eo2, &oracle);
    CHECK(ro.oracle == "seg+t");
    CHECK_THAT(eval::report_markdown(ro), Catch::Contains("Oracle inputs (seg+t)"));
    REQUIRE(plain.size() == 4);
    REQUIRE(oracle.size() == 4);
    for (size_t i = 0; i < plain.size(); ++i) {
        INFO("instance " << i);
        CHECK(plain[i].seg_iou >= 0);
        CHECK(plain[i].seg_iou <= 1);
        CHECK(oracle[i].seg_iou == 1.0);
        REQUIRE(oracle[i].found);
        CHECK(oracle[i].trans_mm < 1e-3);  // the GT translation, rounded to float
    }
    for (const auto& s : ro.objects) CHECK(s.seg_iou == 1.0);
    CHECK(ro.average.seg_iou == 1.0);

    // An inference export: no optimizer state, the same model, loadable by load_model.
    const std::string ex = dir + "/export.g2l";
    const int64_t bytes = train::export_model(dir + "/last.g2l", ex);
    CHECK(bytes == int64_t(fs::file_size(ex)));
    CHECK(bytes < int64_t(fs::file_size(dir + "/last.g2l")) / 2);
    train::LoadedModel e = train::load_model(ex);
    CHECK(e.class_of == m.class_of);
    CHECK(e.points == m.points);
    CHECK(e.seg_points == m.seg_points);
    const auto sd = m.net->state_dict(), sde = e.net->state_dict();
    REQUIRE(sd.size() == sde.size());
    for (const auto& [name, t] : sd) {
        INFO(name);
        REQUIRE(sde.at(name).nbytes() == t.nbytes());
        CHECK(std::memcmp(static_cast<const Tensor&>(sde.at(name)).data(), static_cast<const Tensor&>(t).data(), t.nbytes()) == 0);
    }
    const auto r2 = eval::evaluate_gt_boxes(infer::PipelineModel::of(e), ds, eo);
    CHECK(r2.average.auc_adds == r.average.auc_adds);
    // A training run cannot resume from an export, and bad paths name the file.
    CHECK_THROWS_WITH(train::export_model(cut, dir + "/x.g2l"), Catch::Contains("cut.g2l"));
    CHECK_FALSE(fs::exists(dir + "/x.g2l"));
}

TEST_CASE("g2l_train --average: the mean of a run's checkpoints, loadable, mismatches are named",
          "[train][eval]") {
    const std::string dir = testing::temp_dir("average");
    nlohmann::json j = nlohmann::json::parse(tiny_config(dir + "/run", 2, 8));
    j["train"]["checkpoint_every"] = 1;
    train::TrainOptions opt;
    opt.progress = false;
    train::run_training(train::parse_config_text(j.dump(), "avg.json"), opt);
    const std::string e1 = dir + "/run/epoch_1.g2l", e2 = dir + "/run/epoch_2.g2l";
    REQUIRE(fs::exists(e1));
    REQUIRE(fs::exists(e2));
    const std::string out = dir + "/avg.g2l";
    const int64_t bytes = train::export_average({e1, e2}, out);
    CHECK(bytes == int64_t(fs::file_size(out)));
    const Checkpoint a = load_checkpoint(e1), b = load_checkpoint(e2), m = load_checkpoint(out);
    int differing = 0;
    for (const auto& [name, t] : m.tensors) {
        INFO(name);
        REQUIRE(a.tensors.count("model." + name.substr(6)));
        const Tensor &ta = a.tensors.at(name), &tb = b.tensors.at(name);
        REQUIRE(t.shape() == ta.shape());
        if (t.dtype() != DType::F32) continue;
        for (int64_t k = 0; k < t.numel(); ++k) {
            const double want = (double(ta.data<float>()[k]) + double(tb.data<float>()[k])) / 2;
            REQUIRE(t.data<float>()[k] == Approx(want).margin(1e-6));
            differing += ta.data<float>()[k] != tb.data<float>()[k];
        }
    }
    CHECK(differing > 0);  // the two epochs' weights differ, so the mean is not a copy
    for (const auto& [name, t] : m.tensors) CHECK(name.rfind("model.", 0) == 0);  // no Adam state
    const nlohmann::json meta = nlohmann::json::parse(m.meta_json);
    CHECK(meta.at("format") == "g2l-model");
    REQUIRE(meta.at("trained").at("averaged").size() == 2);
    CHECK(meta["trained"]["averaged"][1]["source"] == e2);
    train::LoadedModel lm = train::load_model(out);
    CHECK(lm.class_of == std::map<int, int>{{8, 0}, {14, 1}});
    // A checkpoint of the same run with itself is itself, to the bit.
    train::export_average({e2, e2}, dir + "/same.g2l");
    const Checkpoint same = load_checkpoint(dir + "/same.g2l");
    for (const auto& [name, t] : same.tensors) {
        INFO(name);
        CHECK(std::memcmp(t.data(), b.tensors.at(name).data(), t.nbytes()) == 0);
    }
    // Bad input: one checkpoint, another network, a truncated file; nothing is written.
    CHECK_THROWS_WITH(train::export_average({e1}, dir + "/x.g2l"), Catch::Contains("at least two"));
    nlohmann::json wide = nlohmann::json::parse(tiny_config(dir + "/wide", 1, 8));
    wide["model"]["width"] = 0.25;
    train::run_training(train::parse_config_text(wide.dump(), "wide.json"), opt);
    CHECK_THROWS_WITH(train::export_average({e1, dir + "/wide/last.g2l"}, dir + "/x.g2l"),
                      Catch::Contains("wide/last.g2l") && Catch::Contains("'model'"));
    const std::string cut = dir + "/cut.g2l";
    fs::copy_file(e2, cut);
    fs::resize_file(cut, fs::file_size(cut) / 3);
    CHECK_THROWS_WITH(train::export_average({e1, cut}, dir + "/x.g2l"), Catch::Contains("cut.g2l"));
    CHECK_FALSE(fs::exists(dir + "/x.g2l"));
}

TEST_CASE("g2l_train: a corrupt validation depth image is reported before the first step",
          "[train][trainer][errors]") {
    const std::string dir = testing::temp_dir("preflight");
    // A copy of the fixture dataset whose second depth image is cut in half.
    const std::string mini = dir + "/ycbv_mini";
    fs::copy(testing::fixture_dir() + "/ycbv_mini", mini, fs::copy_options::recursive);
    const std::string bad = mini + "/train_real/000000/depth/000011.png";
    fs::resize_file(bad, fs::file_size(bad) / 2);
    nlohmann::json j = nlohmann::json::parse(tiny_config(dir + "/run", 1, 8));
    j["data"]["val"][0]["root"] = mini;
    const auto cfg = train::parse_config_text(j.dump(), "p.json");
    train::TrainOptions opt;
    opt.progress = false;
    REQUIRE_THROWS_WITH(train::run_training(cfg, opt), Catch::Contains("000011.png"));
    // Nothing was trained: no step was logged, no checkpoint written.
    CHECK_FALSE(fs::exists(dir + "/run/last.g2l"));
    CHECK(logged(dir + "/run", "loss").empty());
}

namespace {

// The fixture's object-8 frames written again in the Linemod_preprocessed layout (folder
// data/08: rgb, depth, mask, gt.yml, info.yml, train.txt; models/obj_08.ply and
// models_info.yml), the box being BOP's visible box: both readers then describe the same
// frames, instances and boxes.
std::string write_linemod_copy(const std::string& root) {
    const std::string mini = testing::fixture_dir() + "/ycbv_mini";
    data::BopOptions o;
    o.obj_ids = {8};
    const data::BopDataset ds = data::open_bop(mini, "train_real", o);
    const std::string d = root + "/data/08";
    for (const char* sub : {"/rgb", "/depth", "/mask"}) fs::create_directories(d + sub);
    fs::create_directories(root + "/models");
    std::ofstream gt(d + "/gt.yml"), info(d + "/info.yml"), list(d + "/train.txt");
    char stem[16];
    int index = 0;
    for (const data::Frame& f : ds.frames()) {
        REQUIRE(f.instances.size() == 1);
        const data::Instance& in = f.instances[0];
        std::snprintf(stem, sizeof stem, "%04d", index);
        fs::copy_file(f.rgb_path, d + "/rgb/" + stem + ".png");
        fs::copy_file(f.depth_path, d + "/depth/" + stem + ".png");
        fs::copy_file(in.mask_visib_path, d + "/mask/" + stem + ".png");
        gt << index << ":\n- cam_R_m2c: [";
        for (int k = 0; k < 9; ++k) gt << (k ? ", " : "") << nlohmann::json(in.pose.R(k / 3, k % 3)).dump();
        gt << "]\n  cam_t_m2c: [" << nlohmann::json(in.pose.t.x()).dump() << ", "
           << nlohmann::json(in.pose.t.y()).dump() << ", " << nlohmann::json(in.pose.t.z()).dump()
           << "]\n  obj_bb: [" << in.box().x << ", " << in.box().y << ", " << in.box().w << ", "
           << in.box().h << "]\n  obj_id: 8\n";
        info << index << ":\n  cam_K: [" << nlohmann::json(f.K.fx).dump() << ", 0.0, "
             << nlohmann::json(f.K.cx).dump() << ", 0.0, " << nlohmann::json(f.K.fy).dump()
             << ", " << nlohmann::json(f.K.cy).dump() << ", 0.0, 0.0, 1.0]\n  depth_scale: "
             << nlohmann::json(f.depth_scale).dump() << "\n";
        list << stem << "\n";
        ++index;
    }
    REQUIRE(index == 2);
    const data::ObjectModel& m = ds.model(8);
    fs::copy_file(m.mesh_path, root + "/models/obj_08.ply");
    std::ofstream(root + "/models/models_info.yml")
        << "8: {diameter: " << nlohmann::json(m.info.diameter).dump()
        << ", min_x: " << nlohmann::json(m.info.min.x()).dump()
        << ", min_y: " << nlohmann::json(m.info.min.y()).dump()
        << ", min_z: " << nlohmann::json(m.info.min.z()).dump()
        << ", size_x: " << nlohmann::json(m.info.size.x()).dump()
        << ", size_y: " << nlohmann::json(m.info.size.y()).dump()
        << ", size_z: " << nlohmann::json(m.info.size.z()).dump() << "}\n";
    return root;
}

}  // namespace

TEST_CASE("g2l_train: a linemod_preprocessed source trains and validates like the same frames "
          "read as BOP", "[train][trainer]") {
    const std::string dir = testing::temp_dir("train_linemod");
    const std::string lm = write_linemod_copy(dir + "/Linemod_preprocessed");
    const std::string mini = testing::fixture_dir() + "/ycbv_mini";
    auto config = [&](const std::string& run, const nlohmann::json& source) {
        auto j = nlohmann::json::parse(tiny_config(run, 2, 8));
        j["data"]["object_ids"] = {8};
        j["model"]["num_classes"] = 1;
        j["data"]["train"] = {source};
        j["data"]["val"] = {source};
        j["train"]["val_every"] = 1;
        return j;
    };
    const nlohmann::json as_bop = {{"type", "bop"}, {"root", mini}, {"split", "train_real"},
                                   {"objects", {8}}, {"min_visib_fract", 0.0}};
    const nlohmann::json as_lm = {{"type", "linemod_preprocessed"}, {"root", lm},
                                  {"split", "train"}, {"objects", {8}}};
    train::TrainOptions opt;
    opt.progress = false;
    const auto a = train::run_training(
        train::parse_config_text(config(dir + "/bop", as_bop).dump(), "bop.json"), opt);
    const auto b = train::run_training(
        train::parse_config_text(config(dir + "/lm", as_lm).dump(), "lm.json"), opt);
    REQUIRE(a.steps == 4);
    REQUIRE(b.steps == 4);
    // The same samples, so the same losses and weights to the bit; validation ran on both.
    REQUIRE(logged(dir + "/lm", "loss") == logged(dir + "/bop", "loss"));
    require_same_checkpoint(dir + "/bop/last.g2l", dir + "/lm/last.g2l");
    REQUIRE(a.best_val >= 0);
    REQUIRE(b.best_val == a.best_val);
    // The config round-trips the type; keys the reader has no use for are refused.
    const auto cfg = train::parse_config_text(config(dir + "/x", as_lm).dump(), "lm.json");
    REQUIRE(cfg.data.train[0].type == train::SourceType::linemod_preprocessed);
    REQUIRE(train::parse_config_text(train::config_to_json(cfg), "again.json").data.train[0].type ==
            train::SourceType::linemod_preprocessed);
    auto bad = config(dir + "/y", as_lm);
    bad["data"]["train"][0]["scenes"] = {"000000"};
    REQUIRE_THROWS_WITH(train::parse_config_text(bad.dump(), "bad.json"),
                        Catch::Contains("'data.train[0]': a linemod_preprocessed source reads"));
}

TEST_CASE("g2l_train: train.time_schedule decays the learning rate of a run the time limit ends "
          "early", "[train][trainer]") {
    // 20 epochs, lr x0.1 after epoch 10; a 1.8-second limit ends the run in its first epochs.
    auto config = [](const std::string& dir, bool fit) {
        auto j = nlohmann::json::parse(tiny_config(dir, 20, 16));
        j["schedule"] = {{"kind", "step"}, {"step_epochs", 10}, {"gamma", 0.1}};
        j["train"]["time_limit_min"] = 0.03;
        j["train"]["time_schedule"] = fit;
        j["data"]["val"] = nlohmann::json::array();
        return train::parse_config_text(j.dump(), "t.json");
    };
    train::TrainOptions opt;
    opt.progress = false;
    const std::string a = testing::temp_dir("time_fixed"), b = testing::temp_dir("time_fitted");
    const auto sa = train::run_training(config(a, false), opt);
    const auto sb = train::run_training(config(b, true), opt);
    REQUIRE(sa.stopped_early);
    REQUIRE(sb.stopped_early);
    REQUIRE(sb.epochs_done < 10);  // by epochs, the decay would not have come
    const auto la = logged(a, "lr"), lb = logged(b, "lr"), sb_s = logged(b, "step_s");
    INFO(la.size() << " and " << lb.size() << " steps in 1.8 s, the last " << sb_s.back() << " s");
    for (double lr : la) REQUIRE(lr == Approx(1e-3));  // by epochs: never decayed
    // By the clock: the first half of the limit at 1e-3, the second at 1e-4. The last step
    // started at least (limit - its duration) into the run: past half the limit when steps
    // are short (an instrumented build's may not be).
    REQUIRE(lb.front() == Approx(1e-3));
    if (sb_s.back() < 0.4 * 1.8) REQUIRE(lb.back() == Approx(1e-4));
    for (double lr : lb) REQUIRE((lr == Approx(1e-3) || lr == Approx(1e-4)));
}
