// SPDX-License-Identifier: MIT
#include "data/scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include "core/error.h"
#include "core/rng.h"
#include "data/render_primitives.h"

namespace g2l::data {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
// The instance image's value on a block (distractors: -1, targets: k + 1, background: 0).
constexpr int32_t kBlockInstance = -2;

uint64_t mix64(uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

std::string join_ids(const std::vector<int>& ids) {
    std::ostringstream s;
    for (size_t i = 0; i < ids.size(); ++i) s << (i ? ", " : "") << ids[i];
    return s.str();
}

// Uniformly distributed rotation (normalised 4D Gaussian = uniform unit quaternion).
Eigen::Matrix3d random_rotation(Rng& rng) {
    Eigen::Quaterniond q(rng.normal(), rng.normal(), rng.normal(), rng.normal());
    q.normalize();
    return q.toRotationMatrix();
}

Eigen::Matrix3d euler_rotation(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                               Rng& rng) {
    const double a = rng.uniform(lo[0], hi[0]) * kDeg, b = rng.uniform(lo[1], hi[1]) * kDeg;
    const double c = rng.uniform(lo[2], hi[2]) * kDeg;
    return (Eigen::AngleAxisd(c, Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(b, Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
}

// Box of the non-zero pixels of a predicate over the image, and their count.
template <class Pred>
int64_t count_and_box(int W, int H, Pred pred, geom::Box2i& box) {
    int u0 = W, v0 = H, u1 = -1, v1 = -1;
    int64_t n = 0;
    for (int v = 0; v < H; ++v) {
        for (int u = 0; u < W; ++u) {
            if (!pred(size_t(v) * W + u)) continue;
            ++n;
            u0 = std::min(u0, u);
            u1 = std::max(u1, u);
            v0 = std::min(v0, v);
            v1 = std::max(v1, v);
        }
    }
    box = n > 0 ? geom::Box2i{u0, v0, u1 - u0 + 1, v1 - v0 + 1} : geom::Box2i{};
    return n;
}

// Stable poses are computed once per mesh and process (a SceneGenerator is built per epoch).
const std::pair<Eigen::Vector3d, std::vector<geom::StablePose>>& cached_stable_poses(
    const geom::Mesh& mesh) {
    static std::mutex mu;
    static std::map<const geom::Mesh*, std::pair<Eigen::Vector3d, std::vector<geom::StablePose>>> cache;
    std::lock_guard<std::mutex> lock(mu);
    auto it = cache.find(&mesh);
    if (it == cache.end()) {
        const Eigen::Vector3d com = geom::centre_of_mass(mesh);
        it = cache.emplace(&mesh, std::make_pair(com, geom::stable_poses(mesh, com))).first;
    }
    return it->second;
}

/// The stable pose with the highest centre of mass, improbable ones included (stable_poses
/// drops those under 1% by default: a marker standing on its cap is one).
geom::StablePose tallest_stable_pose(const geom::Mesh& mesh, const Eigen::Vector3d& com) {
    geom::StablePoseOptions opt;
    opt.min_probability = 0;
    const std::vector<geom::StablePose> all = geom::stable_poses(mesh, com, opt);
    G2L_CHECK(!all.empty(), "SceneGenerator: mesh '", mesh.path, "' has no stable pose");
    geom::StablePose best = all.front();
    for (const geom::StablePose& p : all)
        if (p.height > best.height) best = p;
    return best;
}

// A box on the table of a "resting" frame: footprint centre, yaw and edge lengths.
struct Block {
    Eigen::Vector2d xy;
    double yaw;
    Eigen::Vector3d size;
};

// The frame's blocks. They keep apart from each other by their inscribed footprint radius.
std::vector<Block> draw_blocks(const SceneConfig& cfg, Rng& rng) {
    std::vector<Block> blocks;
    if (cfg.blocks_max <= 0) return blocks;
    const int nb = int(rng.randint(cfg.blocks_min, cfg.blocks_max + 1));
    for (int b = 0; b < nb; ++b) {
        Block blk;
        for (int a = 0; a < 3; ++a) blk.size[a] = rng.uniform(cfg.block_size_mm[0], cfg.block_size_mm[1]);
        blk.yaw = rng.uniform(0, 360) * kDeg;
        const double r = 0.5 * std::min(blk.size.x(), blk.size.y());
        for (int attempt = 0; attempt < 100; ++attempt) {
            const double rad = cfg.table_spread_mm * std::sqrt(rng.uniform());
            const double ang = rng.uniform(0, 360) * kDeg;
            blk.xy = Eigen::Vector2d(rad * std::cos(ang), rad * std::sin(ang));
            bool ok = true;
            for (const Block& o : blocks)
                ok = ok && (blk.xy - o.xy).norm() >=
                               cfg.separation * (r + 0.5 * std::min(o.size.x(), o.size.y()));
            if (ok) break;
        }
        blocks.push_back(blk);
    }
    return blocks;
}

// Where an object resting on another (posed pu, world frame) stands: the highest vertex of
// the one beneath within `foot` of xy; a coarse mesh (a box of 8 corners) may have no vertex
// under the footprint: then its top.
double support_height(const geom::Mesh& beneath, const geom::Pose& pu, const Eigen::Vector2d& xy,
                      double foot) {
    const geom::Points& V = beneath.vertices;
    const Eigen::Index step = std::max<Eigen::Index>(1, V.rows() / 20000);
    double top = 0, under_foot = -1;  // highest vertex overall / within the footprint
    for (Eigen::Index i = 0; i < V.rows(); i += step) {
        const Eigen::Vector3d q = pu.R * V.row(i).cast<double>().transpose() + pu.t;
        top = std::max(top, q.z());
        if ((q.head<2>() - xy).norm() <= foot) under_foot = std::max(under_foot, q.z());
    }
    return under_foot >= 0 ? under_foot : top;
}

// The lowest world z of the mesh's vertices rotated by R (a leaning object touches its
// support there).
double lowest_vertex(const geom::Mesh& mesh, const Eigen::Matrix3d& R) {
    const geom::Points& V = mesh.vertices;
    const Eigen::Vector3f r2 = R.row(2).cast<float>().transpose();
    const Eigen::Index step = std::max<Eigen::Index>(1, V.rows() / 20000);
    double lo = 1e30;
    for (Eigen::Index i = 0; i < V.rows(); i += step) lo = std::min(lo, double(V.row(i).dot(r2.transpose())));
    return lo;
}

// The camera on the upper hemisphere around `look` (jittered in place), with a small roll:
// its centre C and the world -> camera rotation.
void draw_camera(const SceneConfig& cfg, Rng& rng, Eigen::Vector3d& look, Eigen::Vector3d* C,
                 Eigen::Matrix3d* Rcw) {
    for (int a = 0; a < 3; ++a) look[a] += rng.normal() * cfg.look_at_jitter_mm;
    look.z() = std::max(0.0, look.z());
    const double dist = rng.uniform(cfg.camera_distance[0], cfg.camera_distance[1]);
    const double el = rng.uniform(cfg.camera_elevation[0], cfg.camera_elevation[1]) * kDeg;
    const double az = rng.uniform(0, 360) * kDeg;
    const double roll = rng.uniform(-cfg.camera_roll_max, cfg.camera_roll_max) * kDeg;
    *C = look + dist * Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    const Eigen::Vector3d zc = (look - *C).normalized();
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    Eigen::Vector3d yc = -(up - up.dot(zc) * zc);
    yc = yc.norm() > 1e-9 ? yc.normalized() : Eigen::Vector3d::UnitY();
    Eigen::Vector3d xc = yc.cross(zc);
    const Eigen::Vector3d xr = std::cos(roll) * xc + std::sin(roll) * yc;
    const Eigen::Vector3d yr = -std::sin(roll) * xc + std::cos(roll) * yc;
    Eigen::Matrix3d Rwc;
    Rwc.col(0) = xr;
    Rwc.col(1) = yr;
    Rwc.col(2) = zc;
    *Rcw = Rwc.transpose();
}

}  // namespace

void validate(const SceneConfig& c, const std::string& where) {
    const geom::Intrinsics& K = c.camera;
    G2L_CHECK(K.width > 0 && K.height > 0 && K.fx > 0 && K.fy > 0, where,
              ": camera needs width, height, fx, fy > 0, got ", K.width, " x ", K.height,
              " fx=", K.fx, " fy=", K.fy);
    G2L_CHECK(c.depth_scale > 0, where, ": depth_scale must be > 0, got ", c.depth_scale);
    G2L_CHECK(c.z_min > 0, where, ": z_min must be > 0 mm, got ", c.z_min);
    G2L_CHECK(c.z_min <= c.z_max, where, ": z range inverted: z_min ", c.z_min, " > z_max ",
              c.z_max);
    G2L_CHECK(c.targets_min >= 0 && c.targets_min <= c.targets_max && c.targets_max >= 1, where,
              ": need 0 <= targets_min <= targets_max and targets_max >= 1, got ", c.targets_min,
              " and ", c.targets_max);
    G2L_CHECK(c.kinds_min >= 0 && c.kinds_min <= c.kinds_max, where,
              ": need 0 <= kinds_min <= kinds_max, got ", c.kinds_min, " and ", c.kinds_max);
    G2L_CHECK(c.kinds_max == 0 || (c.kinds_min >= 1 && !c.unique_targets), where,
              ": kinds_min/kinds_max (", c.kinds_min, ", ", c.kinds_max, ") draw copies of a few "
              "objects: they need kinds_min >= 1 and unique_targets false");
    G2L_CHECK(c.distractors_min >= 0 && c.distractors_min <= c.distractors_max, where,
              ": need 0 <= distractors_min <= distractors_max, got ", c.distractors_min, " and ",
              c.distractors_max);
    G2L_CHECK(c.xy_frac > 0 && c.xy_frac <= 1, where, ": xy_frac must be in (0, 1], got ",
              c.xy_frac);
    for (int k = 0; k < 3; ++k) {
        G2L_CHECK(c.euler_min[k] <= c.euler_max[k], where, ": euler_min[", k, "] ",
                  c.euler_min[k], " > euler_max[", k, "] ", c.euler_max[k]);
    }
    G2L_CHECK(c.separation >= 0 && c.separation <= 1, where,
              ": separation must be in [0, 1], got ", c.separation);
    G2L_CHECK(c.support_plane_prob >= 0 && c.support_plane_prob <= 1, where,
              ": support_plane_prob must be in [0, 1], got ", c.support_plane_prob);
    G2L_CHECK(c.plane_tilt_max >= 0 && c.plane_tilt_max < 90, where,
              ": plane_tilt_max must be in [0, 90) degrees, got ", c.plane_tilt_max);
    validate(c.noise, where + ": noise");
    G2L_CHECK(c.pose_mode == "random" || c.pose_mode == "resting", where,
              ": pose_mode must be \"random\" or \"resting\", got \"", c.pose_mode, "\"");
    G2L_CHECK(c.camera_distance[0] > 0 && c.camera_distance[0] <= c.camera_distance[1], where,
              ": camera_distance must be [min, max] with 0 < min <= max (mm), got [",
              c.camera_distance[0], ", ", c.camera_distance[1], "]");
    G2L_CHECK(c.camera_elevation[0] > 0 && c.camera_elevation[0] <= c.camera_elevation[1] &&
                  c.camera_elevation[1] <= 90,
              where, ": camera_elevation must be [min, max] with 0 < min <= max <= 90 degrees, got [",
              c.camera_elevation[0], ", ", c.camera_elevation[1], "]");
    G2L_CHECK(std::isfinite(c.upright_prob) && c.upright_prob >= 0 && c.upright_prob <= 1, where,
              ": upright_prob must be in [0, 1], got ", c.upright_prob);
    for (const auto& [name, p] : {std::pair<const char*, double>{"tall_prob", c.tall_prob},
                                  {"on_block_prob", c.on_block_prob},
                                  {"on_object_prob", c.on_object_prob},
                                  {"lean_prob", c.lean_prob}}) {
        G2L_CHECK(std::isfinite(p) && p >= 0 && p <= 1, where, ": ", name,
                  " must be in [0, 1], got ", p);
    }
    G2L_CHECK(c.blocks_min >= 0 && c.blocks_min <= c.blocks_max && c.blocks_max <= 16, where,
              ": need 0 <= blocks_min <= blocks_max <= 16, got ", c.blocks_min, ", ",
              c.blocks_max);
    G2L_CHECK(std::isfinite(c.block_size_mm[0]) && std::isfinite(c.block_size_mm[1]) &&
                  c.block_size_mm[0] > 0 && c.block_size_mm[0] <= c.block_size_mm[1],
              where, ": block_size_mm must be [min, max] with 0 < min <= max (mm), got [",
              c.block_size_mm[0], ", ", c.block_size_mm[1], "]");
    G2L_CHECK(std::isfinite(c.block_lookalike_tol) && c.block_lookalike_tol >= 0 &&
                  c.block_lookalike_tol <= 1,
              where, ": block_lookalike_tol must be in [0, 1], got ", c.block_lookalike_tol);
    G2L_CHECK(std::isfinite(c.lean_max_deg) && c.lean_max_deg >= 0 && c.lean_max_deg <= 90, where,
              ": lean_max_deg must be in [0, 90] degrees, got ", c.lean_max_deg);
    G2L_CHECK(c.camera_roll_max >= 0 && c.camera_roll_max <= 180, where,
              ": camera_roll_max must be in [0, 180] degrees, got ", c.camera_roll_max);
    G2L_CHECK(c.table_spread_mm >= 0 && std::isfinite(c.table_spread_mm), where,
              ": table_spread_mm must be >= 0, got ", c.table_spread_mm);
    G2L_CHECK(c.look_at_jitter_mm >= 0 && std::isfinite(c.look_at_jitter_mm), where,
              ": look_at_jitter_mm must be >= 0, got ", c.look_at_jitter_mm);
    G2L_CHECK(c.table_size_mm > 0 && std::isfinite(c.table_size_mm), where,
              ": table_size_mm must be > 0, got ", c.table_size_mm);
}

SceneGenerator::SceneGenerator(const SceneConfig& cfg, std::vector<SceneModel> models)
    : cfg_(cfg), renderer_((validate(cfg), cfg.camera)) {
    G2L_CHECK(!models.empty(), "SceneGenerator: empty model list (need at least one mesh)");
    std::vector<int> ids;
    for (const SceneModel& m : models) {
        G2L_CHECK(m.mesh != nullptr, "SceneGenerator: obj_id ", m.obj_id, " has a null mesh");
        G2L_CHECK(m.mesh->faces.rows() > 0 && m.mesh->vertices.rows() > 0,
                  "SceneGenerator: obj_id ", m.obj_id, " mesh '", m.mesh->path,
                  "' has no faces or vertices");
        G2L_CHECK(std::find(ids.begin(), ids.end(), m.obj_id) == ids.end(),
                  "SceneGenerator: duplicated obj_id ", m.obj_id);
        ids.push_back(m.obj_id);
        const Eigen::Vector3f lo = m.mesh->vertices.colwise().minCoeff();
        const Eigen::Vector3f hi = m.mesh->vertices.colwise().maxCoeff();
        const Eigen::Vector3d c = (0.5f * (lo + hi)).cast<double>();
        const double r =
            std::sqrt(double((m.mesh->vertices.rowwise() - c.cast<float>().transpose())
                                 .rowwise()
                                 .squaredNorm()
                                 .maxCoeff()));
        ModelGeom g{m.obj_id, m.mesh, c, std::max(r, 1e-3), c, {}, -1, {}, {}};
        g.extent_sorted = (hi - lo).cast<double>();
        std::sort(g.extent_sorted.data(), g.extent_sorted.data() + 3);
        if (cfg_.pose_mode == "resting") {
            const auto& sp = cached_stable_poses(*m.mesh);
            g.com = sp.first;
            g.stable = sp.second;
            double best = std::cos(30 * kDeg);
            for (size_t i = 0; i < g.stable.size(); ++i)
                if (-double(g.stable[i].down.z()) >= best) {
                    best = -double(g.stable[i].down.z());
                    g.upright = int(i);
                }
            if (cfg_.tall_prob > 0) g.tall = tallest_stable_pose(*m.mesh, g.com);
        }
        models_.push_back(std::move(g));
    }
    targets_ = cfg_.target_obj_ids.empty() ? ids : cfg_.target_obj_ids;
    for (const int id : targets_) {
        G2L_CHECK(std::find(ids.begin(), ids.end(), id) != ids.end(), "SceneGenerator: target ",
                  "obj_id ", id, " is not among the models (", join_ids(ids), ")");
    }
    if (cfg_.distractor_obj_ids.empty()) {
        for (const int id : ids) {
            if (std::find(targets_.begin(), targets_.end(), id) == targets_.end()) {
                distractors_.push_back(id);
            }
        }
    } else {
        distractors_ = cfg_.distractor_obj_ids;
        for (const int id : distractors_) {
            G2L_CHECK(std::find(ids.begin(), ids.end(), id) != ids.end(),
                      "SceneGenerator: distractor obj_id ", id, " is not among the models (",
                      join_ids(ids), ")");
        }
    }
    plane_ = make_quad(1.0, 8);
    plane_unit_ = plane_.vertices;
    plane_.path = "<support plane>";
}

bool SceneGenerator::block_is_lookalike(const Eigen::Vector3d& size) const {
    if (cfg_.block_lookalike_tol <= 0) return true;
    Eigen::Vector3d s = size;
    std::sort(s.data(), s.data() + 3);
    for (const int id : targets_) {
        const Eigen::Vector3d& e = model(id).extent_sorted;
        bool alike = true;
        for (int a = 0; a < 3; ++a)
            alike = alike && std::abs(s[a] - e[a]) <= cfg_.block_lookalike_tol * e[a];
        if (alike) return true;
    }
    return false;
}

const SceneGenerator::ModelGeom& SceneGenerator::model(int obj_id) const {
    for (const ModelGeom& m : models_) {
        if (m.obj_id == obj_id) return m;
    }
    G2L_CHECK(false, "SceneGenerator: unknown obj_id ", obj_id);
    return models_.front();
}

std::vector<int> SceneGenerator::choose_objects(Rng& rng, int* n_targets_out) const {
    // Which objects: targets (annotated, instance ids 1..n) then distractors (id -1).
    std::vector<int> pool = targets_;
    if (cfg_.kinds_max > 0) {  // a bin: a few kinds, the targets copies of them
        const int kinds = std::min<int>(int(rng.randint(cfg_.kinds_min, cfg_.kinds_max + 1)),
                                        int(pool.size()));
        for (int k = 0; k < kinds; ++k) {
            const int j = k + int(rng.below(uint64_t(pool.size()) - uint64_t(k)));
            std::swap(pool[size_t(k)], pool[size_t(j)]);
        }
        pool.resize(size_t(kinds));
    }
    int n_targets = int(rng.randint(cfg_.targets_min, cfg_.targets_max + 1));
    if (cfg_.unique_targets) n_targets = std::min<int>(n_targets, int(pool.size()));
    std::vector<int> chosen;
    for (int k = 0; k < n_targets; ++k) {
        if (cfg_.unique_targets) {  // partial Fisher-Yates: draw without replacement
            const int j = k + int(rng.below(uint64_t(pool.size()) - uint64_t(k)));
            std::swap(pool[size_t(k)], pool[size_t(j)]);
            chosen.push_back(pool[size_t(k)]);
        } else {
            chosen.push_back(pool[size_t(rng.below(pool.size()))]);
        }
    }
    // Distractors never repeat a target of the frame: an unannotated copy of an annotated
    // object would teach "this object is background" (LINEMOD-like scenes list every object as
    // both). With disjoint lists (every config before 2026-12-04) the draws are unchanged.
    int n_distract = int(rng.randint(cfg_.distractors_min, cfg_.distractors_max + 1));
    std::vector<int> dpool;
    for (const int id : distractors_)
        if (std::find(chosen.begin(), chosen.end(), id) == chosen.end()) dpool.push_back(id);
    if (dpool.empty()) n_distract = 0;
    for (int k = 0; k < n_distract; ++k) {
        chosen.push_back(dpool[size_t(rng.below(dpool.size()))]);
    }
    *n_targets_out = n_targets;
    return chosen;
}

std::vector<std::pair<Eigen::Vector3d, double>> SceneGenerator::place_random(
    const std::vector<int>& chosen, int n_targets, Rng& rng) {
    // Poses: centre projects into the central xy_frac of the image at a random depth, and
    // bounding spheres keep apart by `separation`.
    const geom::Intrinsics& K = cfg_.camera;
    const int W = K.width, H = K.height;
    std::vector<std::pair<Eigen::Vector3d, double>> placed;
    for (size_t k = 0; k < chosen.size(); ++k) {
        const ModelGeom& m = model(chosen[k]);
        Eigen::Vector3d p;
        for (int attempt = 0; attempt < 100; ++attempt) {
            const double z = rng.uniform(cfg_.z_min, cfg_.z_max);
            const double u = W * (0.5 + cfg_.xy_frac * (rng.uniform() - 0.5));
            const double v = H * (0.5 + cfg_.xy_frac * (rng.uniform() - 0.5));
            p = Eigen::Vector3d((u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z);
            bool ok = true;
            for (const auto& [q, r] : placed) {
                ok = ok && (p - q).norm() >= cfg_.separation * (r + m.radius);
            }
            if (ok) break;
        }
        placed.emplace_back(p, m.radius);
        RenderObject obj;
        obj.mesh = m.mesh;
        obj.pose.R = cfg_.full_rotation ? random_rotation(rng)
                                        : euler_rotation(cfg_.euler_min, cfg_.euler_max, rng);
        obj.pose.t = p - obj.pose.R * m.center;
        obj.instance_id = k < size_t(n_targets) ? int32_t(k + 1) : -1;  // -1: distractor
        obj.default_color = cfg_.object_color;
        objects_.push_back(obj);
    }
    return placed;
}

void SceneGenerator::add_support_plane(const std::vector<std::pair<Eigen::Vector3d, double>>& placed,
                                       Rng& rng) {
    // Normal tilted from -z, placed behind every bounding sphere.
    const geom::Intrinsics& K = cfg_.camera;
    const int W = K.width, H = K.height;
    const double tilt = rng.uniform(0, cfg_.plane_tilt_max) * kDeg;
    const double az = rng.uniform(0, 360) * kDeg;
    const Eigen::Vector3d n(std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az),
                            -std::cos(tilt));  // points towards the camera
    double d = -1e30;  // plane n.x + d = 0 with n.p + d >= r for all spheres
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& [q, r] : placed) {
        d = std::max(d, r - n.dot(q));
        mean += q;
    }
    d += rng.uniform(0, 100);
    mean /= double(placed.size());
    RenderObject obj;
    obj.pose.R = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n)
                     .toRotationMatrix();
    obj.pose.t = mean - (n.dot(mean) + d) * n;
    const double size = 4.0 * (obj.pose.t.norm() + 500.0) * std::max(W / K.fx, H / K.fy);
    plane_.vertices = plane_unit_ * float(size);
    obj.mesh = &plane_;
    for (int c = 0; c < 3; ++c) {
        obj.default_color[size_t(c)] =
            cfg_.random_background ? uint8_t(rng.randint(40, 230)) : uint8_t(128);
    }
    objects_.push_back(obj);
}

void SceneGenerator::paint_background(RenderedFrame& out, Rng& rng) const {
    // A linear gradient between two random colours plus per-pixel noise.
    const int W = cfg_.camera.width, H = cfg_.camera.height;
    float c0[3], c1[3];
    for (int c = 0; c < 3; ++c) {
        c0[c] = float(rng.uniform(0, 255));
        c1[c] = float(rng.uniform(0, 255));
    }
    const double ang = rng.uniform(0, 360) * kDeg;
    const float gx = float(std::cos(ang)), gy = float(std::sin(ang));
    const float amp = float(rng.uniform(0, 40));
    const float span = std::fabs(gx) * W + std::fabs(gy) * H;
    const float off = std::min(0.0f, gx * W) + std::min(0.0f, gy * H);
    for (int v = 0; v < H; ++v) {
        for (int u = 0; u < W; ++u) {
            const size_t i = size_t(v) * W + u;
            if (full_.depth[i] > 0) continue;
            const float s = (gx * u + gy * v - off) / span;
            const float nz = amp * float(rng.uniform() - 0.5);
            for (int c = 0; c < 3; ++c) {
                const float val = c0[c] + s * (c1[c] - c0[c]) + nz;
                out.rgb[3 * i + c] = uint8_t(std::clamp(val + 0.5f, 0.0f, 255.0f));
            }
        }
    }
}

void SceneGenerator::instance_truth(RenderedFrame& out, const std::vector<int>& chosen,
                                    int n_targets, const RenderOptions& opt) {
    // Full silhouette from a solo render, visible part from the scene's instance image (BOP
    // scene_gt_info semantics).
    const int W = cfg_.camera.width, H = cfg_.camera.height;
    out.instances.resize(size_t(n_targets));
    out.full_masks.resize(size_t(n_targets));
    std::vector<RenderObject> solo(1);
    RenderOptions solo_opt = opt;
    solo_opt.shade = false;  // only the silhouette is needed
    for (int k = 0; k < n_targets; ++k) {
        solo[0] = objects_[size_t(k)];
        renderer_.render(solo, solo_opt, solo_);
        RenderedInstance& gt = out.instances[size_t(k)];
        gt.obj_id = chosen[size_t(k)];
        gt.pose = objects_[size_t(k)].pose;
        std::vector<uint8_t>& fm = out.full_masks[size_t(k)];
        fm.resize(size_t(W) * H);
        for (size_t i = 0; i < fm.size(); ++i) fm[i] = solo_.depth[i] > 0 ? 255 : 0;
        gt.px_count_all = count_and_box(W, H, [&](size_t i) { return fm[i] != 0; }, gt.bbox_obj);
        const uint16_t id = uint16_t(k + 1);
        gt.px_count_visib =
            count_and_box(W, H, [&](size_t i) { return out.mask[i] == id; }, gt.bbox_visib);
        gt.px_count_valid = 0;
        for (size_t i = 0; i < fm.size(); ++i) gt.px_count_valid += fm[i] != 0 && out.depth[i] > 0;
        gt.visib_fract =
            gt.px_count_all > 0 ? double(gt.px_count_visib) / double(gt.px_count_all) : 0.0;
    }
}

void SceneGenerator::render_frame(int64_t index, RenderedFrame& out, int threads) {
    G2L_CHECK(index >= 0, "SceneGenerator::render_frame: frame index must be >= 0, got ", index);
    Rng rng(mix64(cfg_.seed ^ mix64(uint64_t(index) + 0x51ED270B7A3Cull)));
    const geom::Intrinsics& K = cfg_.camera;
    const int W = K.width, H = K.height;
    int n_targets = 0;
    const std::vector<int> chosen = choose_objects(rng, &n_targets);
    objects_.clear();
    const bool resting = cfg_.pose_mode == "resting";
    const std::vector<std::pair<Eigen::Vector3d, double>> placed =
        resting ? place_resting(chosen, n_targets, rng) : place_random(chosen, n_targets, rng);
    if (!resting && rng.uniform() < cfg_.support_plane_prob && !placed.empty())
        add_support_plane(placed, rng);

    RenderOptions opt;
    opt.threads = threads;
    if (cfg_.random_light) {
        const double el = rng.uniform(0, 60) * kDeg, az = rng.uniform(0, 360) * kDeg;
        opt.light.direction = Eigen::Vector3f(float(std::sin(el) * std::cos(az)),
                                              float(std::sin(el) * std::sin(az)),
                                              float(-std::cos(el)));
        opt.light.ambient = float(rng.uniform(0.15, 0.5));
        opt.light.diffuse = float(rng.uniform(0.4, 0.9));
    }
    renderer_.render(objects_, opt, full_);
    out.K = K;
    out.depth_scale = cfg_.depth_scale;
    out.rgb = full_.rgb;
    if (cfg_.random_background) paint_background(out, rng);
    out.depth = full_.depth;
    apply_sensor_noise(cfg_.noise, rng.next_u64(), W, H, full_.cos_view.data(), out.depth.data(),
                       noise_scratch_, threads);
    out.mask.resize(size_t(W) * H);
    out.distractor_mask.resize(size_t(W) * H);
    out.block_mask.resize(size_t(W) * H);
    for (size_t i = 0; i < out.mask.size(); ++i) {
        const int32_t id = full_.instance[i];
        out.mask[i] = uint16_t(std::max(id, 0));
        out.distractor_mask[i] = id < 0 ? 255 : 0;
        out.block_mask[i] = id == kBlockInstance ? 255 : 0;
    }
    instance_truth(out, chosen, n_targets, opt);
}

std::vector<std::pair<Eigen::Vector3d, double>> SceneGenerator::place_resting(
    const std::vector<int>& chosen, int n_targets, Rng& rng) {
    // World frame: the table is z = 0, z points up.
    std::vector<std::pair<Eigen::Vector3d, double>> world;  // centre (world) and radius
    std::vector<geom::Pose> pose_w;
    // Blocks first; objects keep their inscribed footprint radius from them, so an object may
    // touch a block (or lean on it) but not sink into its middle.
    const std::vector<Block> blocks = draw_blocks(cfg_, rng);
    for (size_t k = 0; k < chosen.size(); ++k) {
        const ModelGeom& m = model(chosen[k]);
        // A stable pose drawn with its probability, then a random yaw.
        double u = rng.uniform(), acc = 0;
        size_t sp = m.stable.size() - 1;
        for (size_t i = 0; i < m.stable.size(); ++i) {
            acc += m.stable[i].probability;
            if (u < acc) {
                sp = i;
                break;
            }
        }
        if (cfg_.upright_prob > 0 && k < size_t(n_targets) && m.upright >= 0 &&
            rng.uniform() < cfg_.upright_prob)
            sp = size_t(m.upright);
        const geom::StablePose* rest = &m.stable[sp];
        if (cfg_.tall_prob > 0 && k < size_t(n_targets) && rng.uniform() < cfg_.tall_prob)
            rest = &m.tall;
        const double yaw = rng.uniform(0, 360) * kDeg;
        Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                            geom::resting_rotation(*rest);
        bool lean = false;
        if (cfg_.lean_prob > 0 && rng.uniform() < cfg_.lean_prob) {
            const double axis = rng.uniform(0, 360) * kDeg;
            const double tilt = rng.uniform(0, cfg_.lean_max_deg) * kDeg;
            R = Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis), std::sin(axis), 0))
                    .toRotationMatrix() *
                R;
            lean = true;
        }
        int on = -1;  // the block it rests on
        if (!blocks.empty() && cfg_.on_block_prob > 0 && rng.uniform() < cfg_.on_block_prob)
            on = int(rng.below(blocks.size()));
        int under = -1;  // the object it rests on
        if (on < 0 && k > 0 && cfg_.on_object_prob > 0 && rng.uniform() < cfg_.on_object_prob)
            under = int(rng.below(k));
        Eigen::Vector2d xy = Eigen::Vector2d::Zero();
        for (int attempt = 0; attempt < 100 && under < 0; ++attempt) {
            if (on >= 0) {  // somewhere on the top face's central half
                const Block& b = blocks[size_t(on)];
                const Eigen::Vector2d local(rng.uniform(-0.25, 0.25) * b.size.x(),
                                            rng.uniform(-0.25, 0.25) * b.size.y());
                xy = b.xy + Eigen::Rotation2Dd(b.yaw) * local;
            } else {
                const double rad = cfg_.table_spread_mm * std::sqrt(rng.uniform());
                const double ang = rng.uniform(0, 360) * kDeg;
                xy = Eigen::Vector2d(rad * std::cos(ang), rad * std::sin(ang));
            }
            bool ok = true;
            for (const auto& [q, r] : world)
                ok = ok && (xy - q.head<2>()).norm() >= cfg_.separation * (r + m.radius);
            for (size_t b = 0; b < blocks.size() && on < 0; ++b)
                ok = ok && (xy - blocks[b].xy).norm() >=
                               0.5 * std::min(blocks[b].size.x(), blocks[b].size.y());
            if (ok) break;
        }
        double base = on >= 0 ? blocks[size_t(on)].size.z() : 0.0;
        if (under >= 0) {
            // Over the middle of the object beneath (up to a quarter of its radius off), on
            // its highest vertex within this object's footprint.
            const geom::Pose& pu = pose_w[size_t(under)];
            const ModelGeom& mu = model(chosen[size_t(under)]);
            const double ang = rng.uniform(0, 360) * kDeg, off = 0.25 * mu.radius * rng.uniform();
            xy = world[size_t(under)].first.head<2>() + off * Eigen::Vector2d(std::cos(ang), std::sin(ang));
            base = support_height(*mu.mesh, pu, xy, 0.5 * m.radius);
        }
        geom::Pose pw;
        pw.R = R;
        if (lean) {  // lowest vertex on the support
            pw.t = Eigen::Vector3d(xy.x(), xy.y(), base - lowest_vertex(*m.mesh, R));
        } else {
            pw.t = Eigen::Vector3d(xy.x(), xy.y(), base + rest->height) - R * m.com;
        }
        pose_w.push_back(pw);
        world.emplace_back(pw.R * m.center + pw.t, m.radius);
    }
    // Camera on the upper hemisphere around the look-at point, with a small roll.
    Eigen::Vector3d look = Eigen::Vector3d::Zero();
    for (int k = 0; k < n_targets; ++k) look += world[size_t(k)].first;
    look /= double(std::max(1, n_targets));
    Eigen::Vector3d C;
    Eigen::Matrix3d Rcw;
    draw_camera(cfg_, rng, look, &C, &Rcw);
    std::vector<std::pair<Eigen::Vector3d, double>> placed;
    for (size_t k = 0; k < chosen.size(); ++k) {
        const ModelGeom& m = model(chosen[k]);
        RenderObject obj;
        obj.mesh = m.mesh;
        obj.pose.R = Rcw * pose_w[k].R;
        obj.pose.t = Rcw * (pose_w[k].t - C);
        obj.instance_id = k < size_t(n_targets) ? int32_t(k + 1) : -1;  // -1: distractor
        obj.default_color = cfg_.object_color;
        objects_.push_back(obj);
        placed.emplace_back(Rcw * (world[k].first - C), m.radius);
    }
    blocks_.clear();
    for (const Block& b : blocks) blocks_.push_back(make_box(b.size.x(), b.size.y(), b.size.z()));
    for (size_t b = 0; b < blocks.size(); ++b) {
        RenderObject obj;
        obj.mesh = &blocks_[b];
        obj.pose.R = Rcw * Eigen::AngleAxisd(blocks[b].yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        obj.pose.t = Rcw * (Eigen::Vector3d(blocks[b].xy.x(), blocks[b].xy.y(), 0.5 * blocks[b].size.z()) - C);
        obj.instance_id = block_is_lookalike(blocks[b].size) ? kBlockInstance : -1;
        const uint8_t grey = uint8_t(rng.randint(60, 220));
        obj.default_color = {grey, uint8_t(std::min(255, grey + int(rng.randint(0, 30)))), grey};
        objects_.push_back(obj);
    }
    // The table: a square in z = 0 centred under the look-at point, normal towards the camera.
    RenderObject table;
    table.pose.R = Rcw;
    table.pose.t = Rcw * (Eigen::Vector3d(look.x(), look.y(), 0.0) - C);
    plane_.vertices = plane_unit_ * float(cfg_.table_size_mm);
    table.mesh = &plane_;
    for (int c = 0; c < 3; ++c)
        table.default_color[size_t(c)] =
            cfg_.random_background ? uint8_t(rng.randint(40, 230)) : uint8_t(128);
    objects_.push_back(table);
    return placed;
}

}  // namespace g2l::data
