// SPDX-License-Identifier: MIT
// Training samples (train/sample.h, train/sources.h) on the real YCB-V fixture frames
// (tests/data/ycbv_mini: objects 8 and 14) and on noise-free synthetic renders of the same meshes.
// References are independent of the code under test: the GT visible masks, the raw depth image,
// brute-force nearest distances and brute-force crops.
#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "core/error.h"
#include "data/bop.h"
#include "geometry/camera.h"
#include "testing.h"
#include "train/sample.h"
#include "train/sources.h"

using namespace g2l;
using namespace g2l::train;
using Catch::Contains;

namespace {

data::BopDataset open_mini() {
    return data::open_bop(testing::fixture_dir() + "/ycbv_mini", "train_real");
}

std::map<int, SampleModel> models_of(const data::Dataset& ds) {
    std::map<int, SampleModel> m;
    for (const auto& kv : ds.models()) {
        m[kv.first] = {&ds.load_model_mesh(kv.first), kv.second.info};
    }
    return m;
}

const std::map<int, int> kClasses{{8, 0}, {14, 1}};

// Camera-frame point i of a sample: p = Rm^T (p' - shift) + mean (exact without point noise).
Eigen::Vector3d camera_point(const PoseSample& s, int i) {
    const Eigen::Vector3d q(s.points[3 * i], s.points[3 * i + 1], s.points[3 * i + 2]);
    return s.Rm.cast<double>().transpose() * (q - s.shift.cast<double>()) + s.mean.cast<double>();
}

// Pixel index v * width + u a camera point was back-projected from (integer pixel coordinates).
int pixel_of(const Eigen::Vector3d& p, const geom::Intrinsics& K) {
    const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
    const int iu = static_cast<int>(std::lround(u)), iv = static_cast<int>(std::lround(v));
    REQUIRE(std::abs(u - iu) < 1e-2);
    REQUIRE(std::abs(v - iv) < 1e-2);
    return iv * K.width + iu;
}

// Brute-force nearest distance from q to a point set.
double brute_nearest(const geom::Points& pts, const Eigen::Vector3f& q) {
    double best = std::numeric_limits<double>::infinity();
    for (Eigen::Index i = 0; i < pts.rows(); ++i) {
        best = std::min(best, double((pts.row(i).transpose() - q).squaredNorm()));
    }
    return std::sqrt(best);
}

// Chebyshev distance (pixels) from pixel px to the nearest mask pixel, capped at max_r + 1.
int mask_distance_px(const data::Image& mask, int px, int max_r) {
    const int u = px % mask.w, v = px / mask.w;
    int best = max_r + 1;
    for (int dv = -max_r; dv <= max_r; ++dv) {
        for (int du = -max_r; du <= max_r; ++du) {
            const int uu = u + du, vv = v + dv;
            if (uu < 0 || vv < 0 || uu >= mask.w || vv >= mask.h || mask.at(uu, vv) == 0) continue;
            best = std::min(best, std::max(std::abs(du), std::abs(dv)));
        }
    }
    return best;
}

// Object-labelled points of a sample checked against a visible mask.
struct MaskAgreement {
    int object = 0;      ///< points with label 1
    int inside = 0;      ///< ... whose pixel is inside the mask
    int max_dist_px = 0;  ///< largest distance (px) of an object point from the mask
    double fraction() const { return object > 0 ? double(inside) / object : 0.0; }
};

// `in_mask(px)` says whether pixel index px is in the instance's visible mask; `dist(px)` (only
// called for pixels outside) its distance to the mask in pixels.
template <class InMask, class Dist>
MaskAgreement mask_agreement(const PoseSample& s, const geom::Intrinsics& K, InMask in_mask,
                             Dist dist) {
    MaskAgreement a;
    for (int i = 0; i < static_cast<int>(s.labels.size()); ++i) {
        if (s.labels[i] != 1) continue;
        ++a.object;
        const int px = pixel_of(camera_point(s, i), K);
        if (in_mask(px)) {
            ++a.inside;
        } else {
            a.max_dist_px = std::max(a.max_dist_px, dist(px));
        }
    }
    REQUIRE(a.object == s.num_object_points);
    return a;
}

MaskAgreement real_agreement(const PoseSample& s, const data::Frame& f, const data::Image& mask) {
    return mask_agreement(
        s, f.K, [&](int px) { return mask.data[static_cast<size_t>(px)] != 0; },
        [&](int px) { return mask_distance_px(mask, px, 30); });
}

void require_same(const PoseSample& a, const PoseSample& b) {
    REQUIRE(a.obj_id == b.obj_id);
    REQUIRE(a.points == b.points);
    REQUIRE(a.labels == b.labels);
    REQUIRE(a.R == b.R);
    REQUIRE(a.t == b.t);
    REQUIRE(a.mean == b.mean);
    REQUIRE(a.Rm == b.Rm);
    REQUIRE(a.shift == b.shift);
    REQUIRE(a.centre == b.centre);
}

data::SceneConfig clean_scene() {
    data::SceneConfig sc;
    sc.target_obj_ids = {8, 14};
    sc.targets_min = 1;
    sc.targets_max = 2;
    sc.z_min = 600;
    sc.z_max = 1000;
    sc.noise.enabled = false;
    sc.seed = 5;
    return sc;
}

std::vector<data::SceneModel> scene_models(const data::Dataset& ds) {
    return {{8, &ds.load_model_mesh(8)}, {14, &ds.load_model_mesh(14)}};
}

}  // namespace

// The 8 mm rule (spec §3) also labels the support surface within 8 mm of the object's bottom
// edges: around the flat gelatin box (obj 8, 30 mm tall) that ring is ~10 px wide at 0.8 m and
// holds 9-11 % of the object-labelled points (measured), so per sample the floor is 85 %, the
// pooled fraction must reach 90 %, and no object point may lie further from the mask than the
// ring (16 px: 8 mm + a few mm of GT/sensor error at >= 0.7 m with fx = 1067).
TEST_CASE("real YCB-V samples: object labels fall inside the GT visible mask", "[samples]") {
    const data::BopDataset ds = open_mini();
    const SampleMaker maker(SampleConfig{}, models_of(ds), kClasses);
    BopSource src(ds, maker, 0.1);
    REQUIRE(src.size() == 4);  // 2 frames x objects 8 and 14
    int made = 0;
    MaskAgreement pooled;
    for (int64_t i = 0; i < src.size(); ++i) {
        const data::Frame& f = ds.frames()[src.entries()[i].frame];
        const data::Instance& in = f.instances[src.entries()[i].instance];
        const data::Image mask = ds.load_mask(f, in);
        for (uint64_t seed = 1; seed <= 3; ++seed) {
            Rng rng(seed);
            PoseSample s;
            if (!src.get(i, rng, &s)) continue;
            ++made;
            REQUIRE(s.obj_id == in.obj_id);
            REQUIRE(s.class_index == kClasses.at(in.obj_id));
            REQUIRE(s.points.size() == 1500 * 3);
            REQUIRE(s.labels.size() == 1500);
            const MaskAgreement a = real_agreement(s, f, mask);
            INFO("obj " << in.obj_id << " image " << f.image_id << " seed " << seed << ": "
                        << a.object << " object points, " << a.fraction() << " in the mask, "
                        << "farthest " << a.max_dist_px << " px");
            REQUIRE(a.object >= 10);
            REQUIRE(a.fraction() >= 0.85);
            REQUIRE(a.max_dist_px <= 16);
            pooled.object += a.object;
            pooled.inside += a.inside;
        }
    }
    REQUIRE(made >= 10);  // clean, well-visible instances: nearly every crop is usable
    REQUIRE(pooled.fraction() >= 0.9);
}

TEST_CASE("all real YCB-V objects of ../shared/data: labels agree with the visible masks",
          "[samples][shared]") {
    const auto root = testing::shared_data_dir();
    if (!root) {
        testing::skip_without_shared_data("samples on ../shared/data/ycbv");
        return;
    }
    const data::BopDataset ds = data::open_bop(*root + "/ycbv", "train_real");
    std::map<int, int> classes;
    for (const data::Frame& f : ds.frames()) {
        for (const data::Instance& in : f.instances) classes.emplace(in.obj_id, 0);
    }
    int next = 0;
    for (auto& kv : classes) kv.second = next++;
    std::map<int, SampleModel> models;
    for (const auto& kv : classes) {
        models[kv.first] = {&ds.load_model_mesh(kv.first), ds.model(kv.first).info};
    }
    const SampleMaker maker(SampleConfig{}, models, classes, 3.0);
    BopSource src(ds, maker, 0.1, 12);  // 4 frames of each of the 3 videos
    Rng rng(2024);
    std::map<int, MaskAgreement> per_obj;
    MaskAgreement pooled;
    int made = 0;
    for (int64_t i = 0; i < src.size(); ++i) {
        const data::Frame& f = ds.frames()[src.entries()[i].frame];
        const data::Instance& in = f.instances[src.entries()[i].instance];
        PoseSample s;
        if (!src.get(i, rng, &s)) continue;
        ++made;
        const MaskAgreement a = real_agreement(s, f, ds.load_mask(f, in));
        MaskAgreement& o = per_obj[in.obj_id];
        o.object += a.object;
        o.inside += a.inside;
        pooled.object += a.object;
        pooled.inside += a.inside;
    }
    std::ostringstream msg;
    for (const auto& kv : per_obj) msg << " obj " << kv.first << ": " << kv.second.fraction();
    INFO(made << " of " << src.size() << " samples usable; in-mask fraction per object:"
              << msg.str());
    std::cout << "shared ycbv: " << made << "/" << src.size() << " usable; in-mask" << msg.str()
              << "; pooled " << pooled.fraction() << "\n";
    REQUIRE(made >= src.size() * 9 / 10);
    REQUIRE(pooled.fraction() >= 0.9);
}

TEST_CASE("samples: un-augmenting gives the camera points and the GT pose lives in the same frame",
          "[samples]") {
    const data::BopDataset ds = open_mini();
    SampleConfig cfg;
    cfg.points = 400;
    const SampleMaker maker(cfg, models_of(ds), kClasses);
    BopSource src(ds, maker, 0.0);
    for (int64_t i = 0; i < src.size(); ++i) {
        const data::Frame& f = ds.frames()[src.entries()[i].frame];
        const data::Instance& in = f.instances[src.entries()[i].instance];
        int w = 0, h = 0;
        const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
        Rng rng(100 + i);
        PoseSample s;
        REQUIRE(src.get(i, rng, &s));
        // Rm is a rotation within +-10 deg per Euler angle; |shift| within the configured box.
        REQUIRE((s.Rm.transpose() * s.Rm - Eigen::Matrix3f::Identity()).norm() < 1e-5);
        REQUIRE(s.Rm.determinant() == Approx(1.0).margin(1e-5));
        REQUIRE(std::acos(std::clamp((s.Rm.trace() - 1.0) / 2.0, -1.0, 1.0)) < 3 * 10 * M_PI / 180);
        REQUIRE(s.Rm != Eigen::Matrix3f::Identity());
        for (int k = 0; k < 3; ++k) REQUIRE(std::abs(s.shift[k]) <= cfg.shift_mm[k]);
        // R = Rm R_gt, t = Rm (t_gt - mean) + shift; R is a rotation.
        const Eigen::Matrix3d R_ref = s.Rm.cast<double>() * in.pose.R;
        const Eigen::Vector3d t_ref =
            s.Rm.cast<double>() * (in.pose.t - s.mean.cast<double>()) + s.shift.cast<double>();
        REQUIRE((s.R.cast<double>() - R_ref).norm() < 1e-5);
        REQUIRE((s.t.cast<double>() - t_ref).norm() < 1e-2);
        REQUIRE((s.R.transpose() * s.R - Eigen::Matrix3f::Identity()).norm() < 1e-5);
        REQUIRE(s.R.determinant() == Approx(1.0).margin(1e-5));
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (int j = 0; j < cfg.points; ++j) {
            // The un-augmented point is exactly the back-projection of its depth pixel.
            const Eigen::Vector3d p = camera_point(s, j);
            const int px = pixel_of(p, f.K);
            const double z = depth[static_cast<size_t>(px)];
            REQUIRE(z > 0);
            REQUIRE(std::abs(p.z() - z) < 1e-2);
            mean += p;
        }
        REQUIRE((mean / cfg.points - s.mean.cast<double>()).norm() < 1e-3);
        // Object points, moved into the model frame with the augmented pose, lie within the
        // threshold of the model (brute force); background points do not.
        const geom::Points& model = maker.tree(in.obj_id).points();
        int checked_obj = 0, checked_bg = 0;
        for (int j = 0; j < cfg.points && (checked_obj < 60 || checked_bg < 60); ++j) {
            const Eigen::Vector3f q(s.points[3 * j], s.points[3 * j + 1], s.points[3 * j + 2]);
            const Eigen::Vector3f x = s.R.transpose() * (q - s.t);
            const double d = brute_nearest(model, x);
            if (s.labels[j] == 1 && checked_obj++ < 60) REQUIRE(d < cfg.label_threshold_mm + 1e-2);
            if (s.labels[j] == 0 && checked_bg++ < 60) REQUIRE(d >= cfg.label_threshold_mm - 1e-2);
        }
        REQUIRE(checked_obj >= 10);
    }
}

TEST_CASE("samples: the same rng state gives the identical sample, in any request order",
          "[samples]") {
    const data::BopDataset ds = open_mini();
    const SampleMaker maker(SampleConfig{}, models_of(ds), kClasses);
    BopSource a(ds, maker, 0.0), b(ds, maker, 0.0);
    PoseSample s0, s1, s2, s3;
    Rng r0(42), r1(42), r2(43), warm(1);
    REQUIRE(a.get(3, r0, &s0));
    REQUIRE(b.get(0, warm, &s3));  // b has another frame cached
    REQUIRE(b.get(3, r1, &s1));
    require_same(s0, s1);
    REQUIRE(a.get(3, r2, &s2));
    REQUIRE(s2.points != s0.points);
    REQUIRE(r0.state() == r1.state());
}

TEST_CASE("samples: sphere, slab and frustum crops keep exactly the right box points",
          "[samples]") {
    const data::BopDataset ds = open_mini();
    const data::Frame& f = ds.frames()[1];
    int w = 0, h = 0;
    const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
    const DepthView view{depth.data(), w, h, f.K};
    for (const geom::CropKind crop : {geom::CropKind::sphere, geom::CropKind::slab, geom::CropKind::frustum}) {
        for (const int n : {200000, 1000}) {  // with repeats (all candidates kept) / subset
            SampleConfig cfg;
            cfg.crop = crop;
            cfg.points = n;
            cfg.augment = false;
            const SampleMaker maker(cfg, models_of(ds), kClasses);
            Rng rng(9);
            PoseSample s;
            REQUIRE(maker.make(view, f.instances[0], rng, &s));
            // Brute-force crop of the box's points around the reported centre.
            const double radius = ds.model(f.instances[0].obj_id).info.diameter;
            const geom::Points box_pts = geom::depth_to_points(depth.data(), w, h, f.K, s.box);
            std::set<int> expected;
            for (Eigen::Index i = 0; i < box_pts.rows(); ++i) {
                const Eigen::Vector3f p = box_pts.row(i).transpose();
                const bool keep = crop == geom::CropKind::sphere ? (p - s.centre).norm() < radius
                                  : crop == geom::CropKind::slab ? std::abs(p.z() - s.centre.z()) < radius
                                                   : true;
                if (keep) expected.insert(pixel_of(p.cast<double>(), f.K));
            }
            INFO(geom::to_string(crop) << " N=" << n << ": " << expected.size() << " expected of "
                      << box_pts.rows() << " box points");
            REQUIRE(s.num_candidates == static_cast<int>(expected.size()));
            if (crop == geom::CropKind::frustum) REQUIRE(s.num_candidates == box_pts.rows());
            else REQUIRE(s.num_candidates < box_pts.rows());
            std::set<int> got;
            for (int i = 0; i < n; ++i) {
                const int px = pixel_of(camera_point(s, i), f.K);
                REQUIRE(expected.count(px) == 1);
                got.insert(px);
            }
            // With repeats every candidate is present; without, all N points are distinct.
            REQUIRE(got.size() == (n > s.num_candidates ? expected.size() : size_t(n)));
        }
    }
}

TEST_CASE("samples: unusable crops return false", "[samples]") {
    const data::BopDataset ds = open_mini();
    const data::Frame& f = ds.frames()[0];
    int w = 0, h = 0;
    std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
    const DepthView view{depth.data(), w, h, f.K};
    data::Instance in = f.instances[0];
    PoseSample s;
    Rng rng(3);
    SampleConfig cfg;
    REQUIRE(SampleMaker(cfg, models_of(ds), kClasses).make(view, in, rng, &s));
    cfg.min_points = 1000000;  // more than the whole image
    REQUIRE_FALSE(SampleMaker(cfg, models_of(ds), kClasses).make(view, in, rng, &s));
    const SampleMaker maker(SampleConfig{}, models_of(ds), kClasses);
    data::Instance far = in;
    far.pose.t.z() += 500;  // the model is nowhere near the measured surface: no object point
    REQUIRE_FALSE(maker.make(view, far, rng, &s));
    data::Instance outside = in;
    outside.bbox_visib = {w + 10, 0, 50, 50};  // box entirely right of the image
    REQUIRE_FALSE(maker.make(view, outside, rng, &s));
    std::fill(depth.begin(), depth.end(), 0.f);  // no depth at all
    REQUIRE_FALSE(maker.make(view, in, rng, &s));
}

TEST_CASE("samples: bad config values and inputs throw naming the value", "[samples]") {
    const data::BopDataset ds = open_mini();
    const auto models = models_of(ds);
    const auto bad = [&](auto edit, const std::string& what) {
        SampleConfig c;
        edit(c);
        REQUIRE_THROWS_WITH(SampleMaker(c, models, kClasses), Contains(what));
    };
    bad([](SampleConfig& c) { c.points = 0; }, "points must be > 0, got 0");
    bad([](SampleConfig& c) { c.points = -5; }, "got -5");
    bad([](SampleConfig& c) { c.radius_scale = std::nan(""); }, "radius_scale must be finite");
    bad([](SampleConfig& c) { c.min_points = 0; }, "min_points must be > 0, got 0");
    bad([](SampleConfig& c) { c.box_jitter_frac = 0.7; },
        "box_jitter_frac must be in [0, 0.5], got 0.7");
    bad([](SampleConfig& c) { c.shift_mm[2] = -1; }, "shift_mm[2] must be finite and >= 0, got -1");
    bad([](SampleConfig& c) { c.rot_deg = 200; }, "rot_deg must be in [0, 180], got 200");
    bad([](SampleConfig& c) { c.label_threshold_mm = 0; }, "label_threshold_mm");
    bad([](SampleConfig& c) { c.point_noise_mm = -2; }, "point_noise_mm");
    REQUIRE_NOTHROW(validate(SampleConfig{}));
    SampleConfig zero;
    zero.points = 0;
    REQUIRE_THROWS_WITH(validate(zero, "cfg.json: samples"),
                        Contains("cfg.json: samples: points must be > 0, got 0"));
    REQUIRE_THROWS_WITH(SampleMaker(SampleConfig{}, models, {{8, 0}, {99, 1}}),
                        Contains("obj_id 99 is in the class map but has no model"));
    REQUIRE_THROWS_WITH(SampleMaker(SampleConfig{}, models, {}), Contains("class map"));
    auto null_mesh = models;
    null_mesh[14].mesh = nullptr;
    REQUIRE_THROWS_WITH(SampleMaker(SampleConfig{}, null_mesh, kClasses),
                        Contains("mesh of obj_id 14 is null"));
    auto no_dia = models;
    no_dia[8].info.diameter = -1;
    REQUIRE_THROWS_WITH(SampleMaker(SampleConfig{}, no_dia, kClasses),
                        Contains("diameter of obj_id 8 must be finite and > 0, got -1"));

    const SampleMaker maker(SampleConfig{}, models, {{8, 0}});
    const data::Frame& f = ds.frames()[0];
    int w = 0, h = 0;
    const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
    const DepthView view{depth.data(), w, h, f.K};
    Rng rng(1);
    PoseSample s;
    data::Instance in = f.instances[0];
    in.obj_id = 14;
    REQUIRE_THROWS_WITH(maker.make(view, in, rng, &s),
                        Contains("obj_id 14 is not in the class map (known ids: 8)"));
    in.obj_id = 8;
    REQUIRE_THROWS_WITH(maker.make(view, in, rng, nullptr), Contains("output sample pointer"));
    REQUIRE_THROWS_WITH(maker.make(DepthView{nullptr, w, h, f.K}, in, rng, &s),
                        Contains("depth pointer is null"));
    REQUIRE_THROWS_WITH(maker.make(DepthView{depth.data(), w, 0, f.K}, in, rng, &s),
                        Contains("640 x 0"));
    REQUIRE_THROWS_WITH(maker.make(DepthView{depth.data(), 320, 240, f.K}, in, rng, &s),
                        Contains("intrinsics are for a 640 x 480 image but the depth image is "
                                 "320 x 240"));
    data::Instance nobox = in;
    nobox.bbox_visib = {};
    nobox.bbox_obj = {};
    REQUIRE_THROWS_WITH(maker.make(view, nobox, rng, &s),
                        Contains("neither bbox_visib nor bbox_obj"));
    data::Instance nan_pose = in;
    nan_pose.pose.t.x() = std::nan("");
    REQUIRE_THROWS_WITH(maker.make(view, nan_pose, rng, &s), Contains("pose of obj_id 8"));

    BopSource src(ds, maker, 0.0);
    REQUIRE(src.size() == 2);  // only object 8 has a class
    REQUIRE_THROWS_WITH(src.get(2, rng, &s), Contains("index 2 is outside [0, 2)"));
    REQUIRE_THROWS_WITH(src.get(-1, rng, &s), Contains("index -1"));
    REQUIRE_THROWS_WITH(BopSource(ds, maker, 1.5),
                        Contains("min_visib_fract must be finite and <= 1, got 1.5"));
    data::SceneConfig sc = clean_scene();
    REQUIRE_THROWS_WITH(SyntheticSource(sc, scene_models(ds), maker, 4),
                        Contains("target obj_id 14 has no class"));
    const SampleMaker both(SampleConfig{}, models, kClasses);
    REQUIRE_THROWS_WITH(SyntheticSource(sc, scene_models(ds), both, 0),
                        Contains("frames must be > 0, got 0"));
    REQUIRE_THROWS_WITH(SyntheticSource(sc, scene_models(ds), both, 4, 1, 1.5),
                        Contains("min_visib_fract must be in [0, 1], got 1.5"));
}

TEST_CASE("synthetic samples: instances less visible than min_visib_fract give no sample",
          "[samples]") {
    const data::BopDataset ds = open_mini();
    const SampleMaker maker(SampleConfig{}, models_of(ds), kClasses);
    data::SceneConfig sc = clean_scene();
    sc.targets_min = sc.targets_max = 2;
    sc.separation = 0;  // let the two objects overlap: partial visibility is common
    SyntheticSource all(sc, scene_models(ds), maker, 40, 1, 0.0);
    SyntheticSource strict(sc, scene_models(ds), maker, 40, 1, 0.9);
    int kept_all = 0, kept_strict = 0, partly_hidden = 0;
    for (int64_t i = 0; i < all.size(); ++i) {
        Rng r1(i), r2(i);
        PoseSample a, b;
        const bool ok_a = all.get(i, r1, &a);
        const bool ok_b = strict.get(i, r2, &b);
        kept_all += ok_a;
        kept_strict += ok_b;
        const int k = all.instance_of(i);
        if (k < 0) continue;
        const double v = all.frame(all.frame_of(i)).instances[size_t(k)].visib_fract;
        INFO("index " << i << " visib_fract " << v);
        if (ok_b) REQUIRE(v >= 0.9);  // kept only when visible enough
        if (ok_a && v < 0.9) {
            ++partly_hidden;
            REQUIRE_FALSE(ok_b);
        }
    }
    REQUIRE(partly_hidden > 0);  // the scene did produce occluded instances
    REQUIRE(kept_strict == kept_all - partly_hidden);
}

TEST_CASE("synthetic noise-free samples: labels agree with the rendered instance mask, "
          "deterministic per index", "[samples]") {
    const data::BopDataset ds = open_mini();
    const SampleMaker maker(SampleConfig{}, models_of(ds), kClasses);
    SyntheticSource src(clean_scene(), scene_models(ds), maker, 6);
    REQUIRE(src.size() == 12);
    int made = 0;
    for (int64_t i = 0; i < src.size(); ++i) {
        Rng rng(77 + i);
        PoseSample s;
        if (!src.get(i, rng, &s)) continue;
        ++made;
        const data::RenderedFrame& f = src.frame(src.frame_of(i));
        const int k = src.instance_of(i);
        REQUIRE(s.obj_id == f.instances[k].obj_id);
        const double frac =
            mask_agreement(
                s, f.K, [&](int px) { return f.mask[static_cast<size_t>(px)] == k + 1; },
                [](int) { return 0; })
                .fraction();
        INFO("index " << i << " obj " << s.obj_id << ": " << s.num_object_points
                      << " object points, " << frac << " in the mask");
        REQUIRE(frac >= 0.98);
    }
    REQUIRE(made >= 8);
    PoseSample bad;
    Rng rb0(1);
    REQUIRE_THROWS_WITH(src.get(12, rb0, &bad), Contains("index 12 is outside [0, 12)"));
    REQUIRE_THROWS_WITH(src.frame(6), Contains("frame index 6 is outside [0, 6)"));
    // Same index + same rng state -> same sample, whatever the source rendered before.
    SyntheticSource other(clean_scene(), scene_models(ds), maker, 6);
    PoseSample a, b;
    Rng ra(5), rb(5);
    const bool ok_a = src.get(3, ra, &a);  // src last rendered frame 5
    const bool ok_b = other.get(3, rb, &b);
    REQUIRE(ok_a == ok_b);
    if (ok_a) require_same(a, b);
}

TEST_CASE("sample throughput: BopSource and SyntheticSource samples/s (reported)",
          "[.][samples][bench]") {
    const data::BopDataset ds = open_mini();
    const SampleMaker maker(SampleConfig{}, models_of(ds), kClasses);
    using clock = std::chrono::steady_clock;
    BopSource bop(ds, maker, 0.0);
    Rng rng(1);
    PoseSample s;
    int ok = 0, n = 0;
    auto t0 = clock::now();
    for (int rep = 0; rep < 50; ++rep) {  // each frame's depth decoded once per rep
        for (int64_t i = 0; i < bop.size(); ++i, ++n) ok += bop.get(i, rng, &s);
    }
    double sec = std::chrono::duration<double>(clock::now() - t0).count();
    std::cout << "BopSource: " << n / sec << " samples/s (" << ok << "/" << n << " usable)\n";
    // make() alone on a decoded frame (no PNG decode).
    const data::Frame& f = ds.frames()[0];
    int w = 0, h = 0;
    const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
    const DepthView view{depth.data(), w, h, f.K};
    t0 = clock::now();
    for (int rep = 0; rep < 200; ++rep) maker.make(view, f.instances[rep % 2], rng, &s);
    sec = std::chrono::duration<double>(clock::now() - t0).count();
    std::cout << "SampleMaker::make on a decoded frame: " << 200 / sec << " samples/s\n";
    t0 = clock::now();
    for (int rep = 0; rep < 20; ++rep) ds.load_depth_mm(f, &w, &h);
    sec = std::chrono::duration<double>(clock::now() - t0).count();
    std::cout << "depth PNG decode: " << 20 / sec << " frames/s\n";
    SyntheticSource syn(clean_scene(), scene_models(ds), maker, 40);
    ok = n = 0;
    t0 = clock::now();
    for (int64_t i = 0; i < syn.size(); ++i, ++n) ok += syn.get(i, rng, &s);
    sec = std::chrono::duration<double>(clock::now() - t0).count();
    std::cout << "SyntheticSource: " << n / sec << " samples/s (" << ok << "/" << n
              << " usable, render + crop + label)\n";
}
