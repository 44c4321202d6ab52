// SPDX-License-Identifier: MIT
// The hypotheses road's selection (infer::select_hypotheses) on hand-made verified hypotheses:
// the best score wins a conflict unless the arbiter prefers the depth's evidence of a lower
// one (its features, and how much depth each claims); duplicates and overlaps name their rival
// in the returned order; fill-ins never displace. And the arbiter's fit (eval::fit_arbiter) on
// made-up conflicts.
#include <catch2/catch.hpp>

#include <cmath>

#include "eval/evaluate.h"
#include "infer/frame_pipeline.h"

using g2l::infer::ArbiterModel;
using g2l::infer::HypothesisTuning;
using g2l::infer::Hypothesis;
using g2l::infer::ScoreModel;
using g2l::infer::Verdict;

namespace {

const g2l::geom::Intrinsics kK{600, 600, 320, 240, 640, 480};
const std::map<int, double> kDiameter{{1, 100.0}, {2, 100.0}, {3, 100.0}};

// A posed, verified hypothesis of `obj` at `t` (mm) whose 80 px box agrees with its distance
// (100 mm at 600 mm: ~100 px), its verification's parts given, the score from `tune`'s model.
Hypothesis verified(const HypothesisTuning& tune, int obj, Eigen::Vector3d t, double det,
                    double explained, double violation, double seg_agree,
                    std::vector<int32_t> footprint) {
    Hypothesis h;
    h.cand.obj_id = h.cand.det_obj_id = obj;
    h.cand.det_score = det;
    h.cand.box = {280, 200, 80, 80};
    h.outcome.obj_id = obj;
    h.outcome.status = g2l::infer::PoseStatus::ok;
    h.outcome.box = h.cand.box;
    h.outcome.pose.t = t;
    h.verified = true;
    h.check.explained = explained;
    h.check.violation = violation;
    h.check.occlusion = 1 - explained - violation;
    h.check.seg_agree = seg_agree;
    h.check.score = explained * seg_agree;
    h.check.footprint = std::move(footprint);
    h.score = tune.score_model.probability(h.check, det, false);
    return h;
}

std::vector<int32_t> cells(int from, int to) {
    std::vector<int32_t> v;
    for (int c = from; c < to; ++c) v.push_back(c);
    return v;
}

// The arbiter's order: w . features + footprint x ln(footprint cells).
double strength(const HypothesisTuning& tune, const Hypothesis& h) {
    return ScoreModel::dot(tune.arbiter.w, ScoreModel::features(h.check, h.cand.det_score, false)) +
           tune.arbiter.footprint * ArbiterModel::ln_cells(h.check.footprint.size());
}

}  // namespace

TEST_CASE("select_hypotheses: the arbiter lets the depth's evidence beat a higher detector score "
          "where two objects claim the same depth", "[infer][select]") {
    HypothesisTuning tune;
    // A strong peak whose pose the depth explains poorly, and a weak peak of another object
    // at the same place that the depth explains well: the score model ranks the first higher
    // (its heat weighs most), the arbiter prefers the second.
    const Hypothesis loud = verified(tune, 1, {0, 0, 600}, 0.9, 0.62, 0.25, 0.60, cells(0, 100));
    const Hypothesis right = verified(tune, 2, {5, 0, 600}, 0.3, 1.0, 0.0, 1.0, cells(10, 100));
    REQUIRE(loud.score > right.score);
    REQUIRE(tune.arbiter.prefer(ScoreModel::features(right.check, 0.3, false),
                                ScoreModel::features(loud.check, 0.9, false),
                                ArbiterModel::ln_cells(90), ArbiterModel::ln_cells(100)) > 0.5);
    CHECK(strength(tune, right) > strength(tune, loud));
    // Elsewhere in the frame, a third pose that conflicts with neither.
    const Hypothesis other = verified(tune, 3, {200, 0, 600}, 0.5, 0.9, 0.0, 0.9, cells(500, 560));

    auto out = g2l::infer::select_hypotheses({loud, right, other}, tune, kDiameter, kK, 0.0);
    REQUIRE(out.size() == 3);
    CHECK(out[0].accepted());
    CHECK(out[1].accepted());
    int kept_obj = out[0].cand.obj_id == 3 ? out[1].cand.obj_id : out[0].cand.obj_id;
    CHECK(kept_obj == 2);
    // Accepted first by score: the loud pose (rejected) comes last and names the right one.
    CHECK(out[2].cand.obj_id == 1);
    CHECK(out[2].verdict == Verdict::overlap);
    REQUIRE(out[2].rival >= 0);
    CHECK(out[size_t(out[2].rival)].cand.obj_id == 2);
    CHECK(out[0].score >= out[1].score);

    // Without the arbiter the higher score wins, as before it.
    HypothesisTuning plain = tune;
    plain.arbitrate = false;
    out = g2l::infer::select_hypotheses({loud, right, other}, plain, kDiameter, kK, 0.0);
    REQUIRE(out.size() == 3);
    CHECK(out[2].cand.obj_id == 2);
    CHECK(out[2].verdict == Verdict::overlap);
    CHECK(out[size_t(out[2].rival)].cand.obj_id == 1);

    // The arbiter only decides conflicts: footprints apart, both are kept.
    Hypothesis apart = right;
    apart.check.footprint = cells(200, 290);
    out = g2l::infer::select_hypotheses({loud, apart}, tune, kDiameter, kK, 0.0);
    CHECK(out[0].accepted());
    CHECK(out[1].accepted());

    // A pose the depth explains no better stays rejected, naming the higher score.
    Hypothesis weak = loud;
    weak.cand.obj_id = weak.cand.det_obj_id = weak.outcome.obj_id = 2;
    weak.cand.det_score = 0.3;
    weak.score = tune.score_model.probability(weak.check, 0.3, false);
    out = g2l::infer::select_hypotheses({weak, loud}, tune, kDiameter, kK, 0.0);
    CHECK(out[0].cand.obj_id == 1);
    CHECK(out[0].accepted());
    CHECK(out[1].verdict == Verdict::overlap);
    CHECK(out[1].rival == 0);
}

TEST_CASE("select_hypotheses: of two poses claiming the same depth, the arbiter prefers the one "
          "that claims more of it", "[infer][select]") {
    HypothesisTuning tune;
    REQUIRE(tune.arbiter.footprint > 0);
    CHECK(ArbiterModel::ln_cells(0) == 0.0);
    CHECK(ArbiterModel::ln_cells(1) == 0.0);
    CHECK(ArbiterModel::ln_cells(400) == Approx(std::log(400.0)));
    // A box posed on one face of a larger object (cells 100-179 of its 0-199: 40 % of the
    // object's depth, above overlap_frac), from a louder peak: the depth explains both models
    // alike, but the object claims all of the box's depth and more than as much again.
    const Hypothesis box = verified(tune, 1, {0, 0, 600}, 0.6, 0.8, 0.05, 0.8, cells(100, 180));
    const Hypothesis object = verified(tune, 2, {10, 0, 600}, 0.3, 0.8, 0.05, 0.8, cells(0, 200));
    REQUIRE(box.score > object.score);
    const double p = tune.arbiter.prefer(ScoreModel::features(object.check, 0.3, false),
                                         ScoreModel::features(box.check, 0.6, false),
                                         ArbiterModel::ln_cells(200), ArbiterModel::ln_cells(80));
    CHECK(p > 0.5);
    // The preference is a difference of strengths: P(a over b) = sigmoid(s(a) - s(b)).
    CHECK(p == Approx(ScoreModel::sigmoid(strength(tune, object) - strength(tune, box))));
    auto out = g2l::infer::select_hypotheses({box, object}, tune, kDiameter, kK, 0.0);
    REQUIRE(out.size() == 2);
    CHECK(out[0].cand.obj_id == 2);
    CHECK(out[0].accepted());
    CHECK(out[1].verdict == Verdict::overlap);
    CHECK(out[1].rival == 0);
    // Without the footprint term the louder peak keeps the depth (the features tie but for
    // the detector's score).
    HypothesisTuning blind = tune;
    blind.arbiter.footprint = 0;
    out = g2l::infer::select_hypotheses({box, object}, blind, kDiameter, kK, 0.0);
    CHECK(out[0].cand.obj_id == 1);
    CHECK(out[1].verdict == Verdict::overlap);
}

TEST_CASE("select_hypotheses: a pose that lost to one the arbiter dropped later is tried again",
          "[infer][select]") {
    HypothesisTuning tune;
    // A (loud) claims cells 0-199; B claims 150-199, inside A's; C claims 0-99, inside A's
    // but apart from B. Scores A > B > C; the arbiter prefers A to B and C to A.
    const Hypothesis a = verified(tune, 1, {0, 0, 600}, 0.9, 0.62, 0.25, 0.60, cells(0, 200));
    const Hypothesis b = verified(tune, 2, {60, 0, 600}, 0.9, 0.55, 0.25, 0.55, cells(150, 200));
    const Hypothesis c = verified(tune, 3, {-40, 0, 600}, 0.3, 1.0, 0.0, 1.0, cells(0, 100));
    REQUIRE(a.score > b.score);
    REQUIRE(b.score > c.score);
    REQUIRE(strength(tune, a) > strength(tune, b));
    REQUIRE(strength(tune, c) > strength(tune, a));
    const auto out = g2l::infer::select_hypotheses({c, a, b}, tune, kDiameter, kK, 0.0);
    REQUIRE(out.size() == 3);
    // B first lost to A; A then lost to C; B, apart from C, is kept after all.
    CHECK(out[0].accepted());
    CHECK(out[1].accepted());
    CHECK(out[0].cand.obj_id == 2);  // accepted by score: B before C
    CHECK(out[1].cand.obj_id == 3);
    CHECK(out[2].cand.obj_id == 1);
    CHECK(out[2].verdict == Verdict::overlap);
    CHECK(out[2].rival == 1);
    for (const auto& h : out)  // every rival named is a kept pose
        if (h.rival >= 0) CHECK(out[size_t(h.rival)].accepted());
}

TEST_CASE("select_hypotheses: duplicates of one object, fill-ins, thresholds and verdicts kept",
          "[infer][select]") {
    HypothesisTuning tune;
    // Two poses of object 1 whose centres lie 20 mm apart (< 0.5 x 100 mm) and that claim
    // some of the same depth (40 of good's 50 cells): one instance. The lower-scored one fits
    // the depth better: the arbiter keeps it, the other is its duplicate.
    const Hypothesis hot = verified(tune, 1, {0, 0, 600}, 0.9, 0.6, 0.3, 0.6, cells(0, 50));
    const Hypothesis good = verified(tune, 1, {20, 0, 600}, 0.3, 1.0, 0.0, 1.0, cells(10, 60));
    REQUIRE(hot.score > good.score);
    auto out = g2l::infer::select_hypotheses({hot, good}, tune, kDiameter, kK, 0.0);
    REQUIRE(out.size() == 2);
    CHECK(out[0].accepted());
    CHECK(out[0].outcome.pose.t.x() == 20.0);
    CHECK(out[1].verdict == Verdict::duplicate);
    CHECK(out[1].rival == 0);
    // 60 mm apart, depth apart: two instances, both kept.
    Hypothesis far = good;
    far.outcome.pose.t.x() = 60;
    far.check.footprint = cells(300, 350);
    out = g2l::infer::select_hypotheses({hot, far}, tune, kDiameter, kK, 0.0);
    CHECK(out[0].accepted());
    CHECK(out[1].accepted());
    // Copies of one part touching in a bin: centres as close as the duplicate's, but claiming
    // other pixels (2 of 50 cells shared, below duplicate_overlap): two instances.
    Hypothesis beside = good;
    beside.check.footprint = cells(48, 98);
    out = g2l::infer::select_hypotheses({hot, beside}, tune, kDiameter, kK, 0.0);
    CHECK(out[0].accepted());
    CHECK(out[1].accepted());
    // Unverified poses have no footprint: their centres decide alone.
    Hypothesis blind_hot = hot, blind = beside;
    blind_hot.verified = blind.verified = false;
    out = g2l::infer::select_hypotheses({blind_hot, blind}, tune, kDiameter, kK, 0.0);
    CHECK(out[0].accepted());
    CHECK(out[1].verdict == Verdict::duplicate);

    // A fill-in (a followed pose) never displaces a fresh one, however well it fits.
    Hypothesis fill = good;
    fill.fill_in = true;
    fill.tracked = true;
    out = g2l::infer::select_hypotheses({fill, hot}, tune, kDiameter, kK, 0.0);
    CHECK(out[0].outcome.pose.t.x() == 0.0);
    CHECK(out[0].accepted());
    CHECK(out[1].fill_in);
    CHECK(out[1].verdict == Verdict::duplicate);

    // Below the threshold: low_score, never a rival; the one above is kept alone.
    out = g2l::infer::select_hypotheses({hot, good}, tune, kDiameter, kK,
                                        0.5 * (hot.score + good.score));
    CHECK(out[0].accepted());
    CHECK(out[0].outcome.pose.t.x() == 0.0);
    CHECK(out[1].verdict == Verdict::low_score);
    CHECK(out[1].rival == -1);

    // Covered hypotheses keep their verdict; one without a pose is no_pose; a pose 10 m away
    // from an 80 px box is implausible.
    Hypothesis covered = good;
    covered.verdict = Verdict::covered;
    covered.outcome.status = g2l::infer::PoseStatus::no_depth;
    Hypothesis lost = good;
    lost.outcome.status = g2l::infer::PoseStatus::no_depth;
    Hypothesis far_away = good;
    far_away.outcome.pose.t = {0, 0, 10000};
    out = g2l::infer::select_hypotheses({covered, lost, far_away}, tune, kDiameter, kK, 0.0);
    REQUIRE(out.size() == 3);
    int n_cov = 0, n_none = 0, n_imp = 0;
    for (const auto& h : out) {
        n_cov += h.verdict == Verdict::covered;
        n_none += h.verdict == Verdict::no_pose;
        n_imp += h.verdict == Verdict::implausible;
    }
    CHECK(n_cov == 1);
    CHECK(n_none == 1);
    CHECK(n_imp == 1);
    // A posed object without a diameter is an error naming it.
    Hypothesis unknown = good;
    unknown.cand.obj_id = 9;
    CHECK_THROWS_WITH(g2l::infer::select_hypotheses({unknown}, tune, kDiameter, kK, 0.0),
                      Catch::Contains("object 9") && Catch::Contains("diameter"));
}

TEST_CASE("same_instance: one object, near, and sharing depth when both are verified",
          "[infer][select]") {
    // The rule of the selection's duplicates and of the tracker's id hand-over.
    using g2l::infer::same_instance;
    HypothesisTuning tune;
    const Hypothesis a = verified(tune, 1, {0, 0, 600}, 0.9, 0.9, 0.0, 0.9, cells(0, 50));
    Hypothesis b = verified(tune, 1, {20, 0, 600}, 0.5, 0.9, 0.0, 0.9, cells(10, 60));
    CHECK(same_instance(a, b, tune, 100.0));        // 40 of 50 cells shared, 20 mm apart
    CHECK(same_instance(b, a, tune, 100.0));
    CHECK_FALSE(same_instance(a, b, tune, 30.0));   // 20 mm >= 0.5 x 30 mm
    Hypothesis beside = b;
    beside.check.footprint = cells(48, 98);         // 2 of 50 shared: a touching copy
    CHECK_FALSE(same_instance(a, beside, tune, 100.0));
    tune.duplicate_overlap = 0.02;                  // 0.04 > 0.02: one instance again
    CHECK(same_instance(a, beside, tune, 100.0));
    tune.duplicate_overlap = 0.1;
    // The precomputed overlap is what decides for verified poses ...
    CHECK(same_instance(a, beside, tune, 100.0, 0.5));
    CHECK_FALSE(same_instance(a, b, tune, 100.0, 0.05));
    // ... and is ignored for an unverified one: the centres alone.
    beside.verified = false;
    CHECK(same_instance(a, beside, tune, 100.0));
    CHECK(same_instance(a, beside, tune, 100.0, 0.0));
    Hypothesis other = b;                           // another object at the same place
    other.cand.obj_id = 2;
    CHECK_FALSE(same_instance(a, other, tune, 100.0));
}

TEST_CASE("fit_arbiter: learns which parts tell the right pose of a conflict, bad input named",
          "[infer][select][eval]") {
    using g2l::eval::HypothesisRecord;
    // Frames of two hypotheses each: a loser (overlap, rival 0) and its winner. The right one
    // of each pair has the higher explained share; the detector's score says nothing (random).
    std::vector<HypothesisRecord> hs;
    uint32_t seed = 7;
    auto rnd = [&] { seed = seed * 1664525u + 1013904223u; return double(seed >> 8) / 16777216.0; };
    for (int f = 0; f < 60; ++f) {
        HypothesisRecord w, l;
        w.scene = l.scene = "000000";
        w.image_id = l.image_id = f;
        w.verdict = "accepted";
        l.verdict = f % 3 ? "overlap" : "duplicate";
        l.rival = 0;
        w.posed = l.posed = w.verified = l.verified = true;
        const bool loser_right = f % 2 == 0;
        for (HypothesisRecord* h : {&w, &l}) {
            const bool right = (h == &l) == loser_right;
            h->pose_right = right;
            h->features = {1.0, right ? 0.8 + 0.2 * rnd() : 0.4 + 0.3 * rnd(), 0.1 * rnd(),
                           0.1, 0.9, 0.5, std::log(0.1 + 0.8 * rnd()), 0.0};
        }
        hs.push_back(w);
        hs.push_back(l);
    }
    const ArbiterModel am = g2l::eval::fit_arbiter(hs);
    CHECK(am.w[0] == 0.0);
    CHECK(am.w[1] > 2.0);                      // the explained share decides
    CHECK(std::abs(am.w[6]) < 0.5 * am.w[1]);  // the detector's score does not
    int agree = 0;
    for (size_t i = 1; i < hs.size(); i += 2)
        agree += (am.prefer(hs[i].features, hs[i - 1].features) > 0.5) == hs[i].pose_right;
    CHECK(agree >= 57);  // of 60
    // prefer is a probability, symmetric: P(a over b) + P(b over a) = 1.
    CHECK(am.prefer(hs[0].features, hs[1].features) + am.prefer(hs[1].features, hs[0].features) ==
          Approx(1.0));

    // Footprint sizes unknown to the records (all 0): the footprint term has nothing to fit.
    CHECK(am.footprint == Approx(0.0).margin(1e-9));

    // Features that say nothing and footprints that do: the right pose of each pair claims
    // more depth (100-139 cells against 40-79).
    std::vector<HypothesisRecord> fp = hs;
    for (size_t i = 0; i < fp.size(); ++i) {
        fp[i].features = {1.0, 0.5 + 0.2 * rnd(), 0.05, 0.1, 0.9, 0.5, std::log(0.2 + 0.6 * rnd()), 0.0};
        fp[i].footprint_cells = fp[i].pose_right ? 100 + int(40 * rnd()) : 40 + int(40 * rnd());
    }
    const ArbiterModel af = g2l::eval::fit_arbiter(fp);
    CHECK(af.footprint > 2.0);
    CHECK(std::abs(af.w[1]) < 0.5 * af.footprint);
    agree = 0;
    for (size_t i = 1; i < fp.size(); i += 2)
        agree += (af.prefer(fp[i].features, fp[i - 1].features,
                            ArbiterModel::ln_cells(size_t(fp[i].footprint_cells)),
                            ArbiterModel::ln_cells(size_t(fp[i - 1].footprint_cells))) > 0.5) ==
                 fp[i].pose_right;
    CHECK(agree == 60);

    // Too few conflicts with one right pose, or a rival outside its frame: named.
    std::vector<HypothesisRecord> few(hs.begin(), hs.begin() + 10);
    CHECK_THROWS_WITH(g2l::eval::fit_arbiter(few), Catch::Contains("at least 10"));
    std::vector<HypothesisRecord> bad = hs;
    bad[1].rival = 5;
    CHECK_THROWS_WITH(g2l::eval::fit_arbiter(bad),
                      Catch::Contains("rival 5") && Catch::Contains("image 0"));
}
