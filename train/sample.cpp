// SPDX-License-Identifier: MIT
// SampleMaker: (depth frame, GT instance) -> PoseSample. See sample.h and spec §6.
#include "train/sample.h"

#include "geometry/crop.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "core/error.h"
#include "geometry/camera.h"

namespace g2l::train {

namespace {

// Fewer object points than this among the N sampled points and the sample is dropped: the
// official demo treats < 10 segmented points as "No object pts" (spec §1.4).
constexpr int kMinObjectPoints = 10;
// Random draws tried before the centre pick falls back to labelling every box point.
constexpr int kCentrePickTries = 64;
constexpr double kPi = 3.14159265358979323846;

std::string known_ids(const std::map<int, int>& m) {
    std::ostringstream s;
    const char* sep = "";
    for (const auto& kv : m) {
        s << sep << kv.first;
        sep = ", ";
    }
    return s.str();
}

// Per-point labels computed on demand: labelling every box point costs one KD-tree query each
// (tens of thousands per frame), while a sample needs about N + a few. Points whose distance to
// the tree's bounding box is already >= the threshold are background without a query (exact:
// every tree point lies in that box).
class LazyLabels {
public:
    LazyLabels(const geom::Points& pts, const geom::ModelKdTree& tree, const Eigen::Vector3f& lo,
               const Eigen::Vector3f& hi, const geom::Pose& pose, float threshold_mm)
        : pts_(pts), tree_(tree), lo_(lo), hi_(hi), Rt_(pose.R.transpose()), t_(pose.t),
          thr_(threshold_mm), cache_(static_cast<size_t>(pts.rows()), int8_t(-1)) {}

    // 1 if R^T (p_i - t) lies within the threshold of the model (same rule as
    // geom::ModelKdTree::label_points), else 0.
    int operator()(int i) {
        int8_t& c = cache_[static_cast<size_t>(i)];
        if (c < 0) {
            const Eigen::Vector3d pc = pts_.row(i).cast<double>().transpose();
            const Eigen::Vector3f pm = (Rt_ * (pc - t_)).cast<float>();
            const Eigen::Vector3f out =
                (lo_ - pm).cwiseMax(pm - hi_).cwiseMax(Eigen::Vector3f::Zero());
            c = out.squaredNorm() >= thr_ * thr_ ? 0 : (tree_.nearest(pm) < thr_ ? 1 : 0);
        }
        return c;
    }

private:
    const geom::Points& pts_;
    const geom::ModelKdTree& tree_;
    Eigen::Vector3f lo_, hi_;  // bounding box of the tree points (model frame)
    Eigen::Matrix3d Rt_;
    Eigen::Vector3d t_;
    float thr_;
    std::vector<int8_t> cache_;
};

// Each edge of `b` moves by U(-f, f) x its width/height; the result is clipped to the image.
geom::Box2i jitter_box(const geom::Box2i& b, double f, int width, int height, Rng& rng) {
    const double x0 = b.x + rng.uniform(-f, f) * b.w;
    const double y0 = b.y + rng.uniform(-f, f) * b.h;
    const double x1 = b.x + b.w + rng.uniform(-f, f) * b.w;
    const double y1 = b.y + b.h + rng.uniform(-f, f) * b.h;
    const int ix0 = static_cast<int>(std::max(0.0, std::round(x0)));
    const int iy0 = static_cast<int>(std::max(0.0, std::round(y0)));
    const int ix1 = static_cast<int>(std::min(double(width), std::round(x1)));
    const int iy1 = static_cast<int>(std::min(double(height), std::round(y1)));
    return {ix0, iy0, std::max(0, ix1 - ix0), std::max(0, iy1 - iy0)};
}

// A uniformly random object-labelled point index, or -1 when the set has none. Rejection
// sampling over uniform draws is exactly uniform over the object points; the fallback (label
// everything) keeps that property when objects cover little of the box.
int pick_object_point(int n, LazyLabels& label, Rng& rng) {
    for (int k = 0; k < kCentrePickTries; ++k) {
        const int i = static_cast<int>(rng.below(uint64_t(n)));
        if (label(i) == 1) return i;
    }
    std::vector<int> obj;
    for (int i = 0; i < n; ++i) {
        if (label(i) == 1) obj.push_back(i);
    }
    if (obj.empty()) return -1;
    return obj[rng.below(obj.size())];
}

// n indices out of `kept`: a random subset without replacement when kept has at least n, else
// every kept index once (shuffled) followed by uniform random repeats.
std::vector<int> sample_indices(std::vector<int> kept, int n, Rng& rng) {
    const size_t m = kept.size();
    const size_t shuffled = std::min(m, size_t(n));
    for (size_t i = 0; i < shuffled; ++i) {  // partial Fisher-Yates
        const size_t j = i + rng.below(m - i);
        std::swap(kept[i], kept[j]);
    }
    kept.resize(shuffled);
    while (kept.size() < size_t(n)) kept.push_back(kept[rng.below(m)]);
    return kept;
}

// Rm = Rz(c) Ry(b) Rx(a), angles U(-deg, deg) drawn in the order a, b, c.
Eigen::Matrix3d random_rotation(double deg, Rng& rng) {
    const double a = rng.uniform(-deg, deg) * kPi / 180.0;
    const double b = rng.uniform(-deg, deg) * kPi / 180.0;
    const double c = rng.uniform(-deg, deg) * kPi / 180.0;
    return (Eigen::AngleAxisd(c, Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(b, Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
}


// Writes out->points = Rm (p - mean) + s (+ noise) for the rows idx of pts, and the GT pose,
// mean, Rm and shift in that frame: R' = Rm R, t' = Rm (t - mean) + s, so p' = R' x + t' holds
// for any model point x with p = R x + t.
void augment_into(const SampleConfig& cfg, const geom::Points& pts, const std::vector<int>& idx,
                  const Eigen::Vector3d& mean, const geom::Pose& pose, Rng& rng,
                  PoseSample* out) {
    Eigen::Matrix3d Rm = Eigen::Matrix3d::Identity();
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    if (cfg.augment) {
        Rm = random_rotation(cfg.rot_deg, rng);
        for (int k = 0; k < 3; ++k) s[k] = rng.uniform(-cfg.shift_mm[k], cfg.shift_mm[k]);
    }
    const double noise = cfg.augment ? cfg.point_noise_mm : 0.0;
    const size_t n = idx.size();
    out->points.resize(n * 3);
    for (size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d p = Rm * (pts.row(idx[i]).cast<double>().transpose() - mean) + s;
        for (int k = 0; k < 3; ++k) {
            const double e = noise > 0 ? rng.normal(0.0, noise) : 0.0;
            out->points[i * 3 + k] = static_cast<float>(p[k] + e);
        }
    }
    out->R = (Rm * pose.R).cast<float>();
    out->t = (Rm * (pose.t - mean) + s).cast<float>();
    out->mean = mean.cast<float>();
    out->Rm = Rm.cast<float>();
    out->shift = s.cast<float>();
}

}  // namespace

void validate(const SampleConfig& c, const std::string& where) {
    G2L_CHECK(c.points > 0, where, ": points must be > 0, got ", c.points);
    G2L_CHECK(c.min_points > 0, where, ": min_points must be > 0, got ", c.min_points);
    G2L_CHECK(std::isfinite(c.radius_scale) && c.radius_scale > 0, where,
              ": radius_scale must be finite and > 0, got ", c.radius_scale);
    G2L_CHECK(std::isfinite(c.label_threshold_mm) && c.label_threshold_mm > 0, where,
              ": label_threshold_mm must be finite and > 0, got ", c.label_threshold_mm);
    G2L_CHECK(std::isfinite(c.center_jitter_mm) && c.center_jitter_mm >= 0, where,
              ": center_jitter_mm must be finite and >= 0, got ", c.center_jitter_mm);
    G2L_CHECK(std::isfinite(c.point_noise_mm) && c.point_noise_mm >= 0, where,
              ": point_noise_mm must be finite and >= 0, got ", c.point_noise_mm);
    G2L_CHECK(c.box_jitter_frac >= 0 && c.box_jitter_frac <= 0.5, where,
              ": box_jitter_frac must be in [0, 0.5], got ", c.box_jitter_frac);
    G2L_CHECK(c.rot_deg >= 0 && c.rot_deg <= 180, where, ": rot_deg must be in [0, 180], got ",
              c.rot_deg);
    for (int i = 0; i < 3; ++i) {
        G2L_CHECK(std::isfinite(c.shift_mm[i]) && c.shift_mm[i] >= 0, where, ": shift_mm[", i,
                  "] must be finite and >= 0, got ", c.shift_mm[i]);
    }
}

SampleMaker::SampleMaker(SampleConfig cfg, const std::map<int, SampleModel>& models,
                         std::map<int, int> class_index, double surface_spacing_mm)
    : cfg_(std::move(cfg)), class_index_(std::move(class_index)) {
    validate(cfg_);
    G2L_CHECK(!class_index_.empty(), "SampleMaker: the class map (obj_id -> class index) is empty");
    for (const auto& [obj_id, cls] : class_index_) {
        G2L_CHECK(cls >= 0, "SampleMaker: class index of obj_id ", obj_id, " must be >= 0, got ",
                  cls);
        const auto it = models.find(obj_id);
        G2L_CHECK(it != models.end(), "SampleMaker: obj_id ", obj_id,
                  " is in the class map but has no model");
        const SampleModel& m = it->second;
        G2L_CHECK(m.mesh != nullptr, "SampleMaker: mesh of obj_id ", obj_id, " is null");
        G2L_CHECK(m.mesh->vertices.rows() > 0, "SampleMaker: mesh of obj_id ", obj_id, " ('",
                  m.mesh->path, "') has no vertices");
        G2L_CHECK(std::isfinite(m.info.diameter) && m.info.diameter > 0,
                  "SampleMaker: diameter of obj_id ", obj_id, " must be finite and > 0, got ",
                  m.info.diameter);
        geom::ModelKdTree tree = geom::ModelKdTree::from_mesh(*m.mesh, surface_spacing_mm);
        const Eigen::Vector3f lo = tree.points().colwise().minCoeff().transpose();
        const Eigen::Vector3f hi = tree.points().colwise().maxCoeff().transpose();
        objects_.emplace(obj_id, Object{m.info, std::move(tree), lo, hi});
    }
}

const SampleMaker::Object& SampleMaker::object(int obj_id) const {
    const auto it = objects_.find(obj_id);
    G2L_CHECK(it != objects_.end(), "SampleMaker: obj_id ", obj_id,
              " is not in the class map (known ids: ", known_ids(class_index_), ")");
    return it->second;
}

int SampleMaker::class_of(int obj_id) const {
    object(obj_id);
    return class_index_.at(obj_id);
}

const geom::ModelKdTree& SampleMaker::tree(int obj_id) const { return object(obj_id).tree; }

const geom::ModelInfo& SampleMaker::info(int obj_id) const { return object(obj_id).info; }

bool SampleMaker::make(const DepthView& view, const data::Instance& inst, Rng& rng,
                       PoseSample* out) const {
    G2L_CHECK(out != nullptr, "SampleMaker::make: output sample pointer is null");
    const Object& obj = object(inst.obj_id);
    G2L_CHECK(inst.pose.R.allFinite() && inst.pose.t.allFinite(), "SampleMaker::make: pose of "
              "obj_id ", inst.obj_id, " is not finite");
    const geom::Box2i& box0 = inst.box();
    G2L_CHECK(!box0.empty(), "SampleMaker::make: instance ", inst.index_in_frame, " (obj_id ",
              inst.obj_id, ") has neither bbox_visib nor bbox_obj");
    G2L_CHECK(view.depth_mm != nullptr, "SampleMaker::make: depth pointer is null");
    G2L_CHECK(view.width > 0 && view.height > 0, "SampleMaker::make: depth image size must be "
              "positive, got ", view.width, " x ", view.height);
    G2L_CHECK((view.K.width == 0 || view.K.width == view.width) &&
                  (view.K.height == 0 || view.K.height == view.height),
              "SampleMaker::make: intrinsics are for a ", view.K.width, " x ", view.K.height,
              " image but the depth image is ", view.width, " x ", view.height);

    // 1. Jittered 2D box (a detector's box is never exact) and its valid depth.
    const geom::Box2i box = jitter_box(box0, cfg_.box_jitter_frac, view.width, view.height, rng);
    if (box.empty()) return false;
    const geom::Points pts =
        geom::depth_to_points(view.depth_mm, view.width, view.height, view.K, box);
    const int n_box = static_cast<int>(pts.rows());
    if (n_box < cfg_.min_points) return false;
    LazyLabels label(pts, obj.tree, obj.lo, obj.hi, inst.pose,
                     static_cast<float>(cfg_.label_threshold_mm));

    // 2. Crop centre: the detector's peak lifted with depth lands on the visible surface, so a
    //    random object point, jittered (spec §1.2, §6 chooselimt).
    const int pick = pick_object_point(n_box, label, rng);
    if (pick < 0) return false;
    Eigen::Vector3d centre = pts.row(pick).cast<double>().transpose();
    for (int k = 0; k < 3; ++k) centre[k] += rng.normal(0.0, cfg_.center_jitter_mm);

    // 3. Crop.
    std::vector<int> kept =
        geom::crop_indices(cfg_.crop, pts, centre, cfg_.radius_scale * obj.info.diameter);
    if (static_cast<int>(kept.size()) < cfg_.min_points) return false;
    const int n_kept = static_cast<int>(kept.size());

    // 4. Sample N points and label them.
    const std::vector<int> idx = sample_indices(std::move(kept), cfg_.points, rng);
    const int n = cfg_.points;
    out->labels.resize(static_cast<size_t>(n));
    int n_obj = 0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i) {
        out->labels[i] = label(idx[i]);
        n_obj += out->labels[i];
        mean += pts.row(idx[i]).cast<double>().transpose();
    }
    if (n_obj < kMinObjectPoints) return false;

    // 5. Augment: p' = Rm (p - mean) + s (+ noise); the GT pose follows into the same frame.
    mean /= n;
    augment_into(cfg_, pts, idx, mean, inst.pose, rng, out);
    out->obj_id = inst.obj_id;
    out->class_index = class_index_.at(inst.obj_id);
    out->num_object_points = n_obj;
    out->centre = centre.cast<float>();
    out->box = box;
    out->num_candidates = n_kept;
    return true;
}

}  // namespace g2l::train
