// SPDX-License-Identifier: MIT
// Rasterizer and sensor-noise tests: geometry checked against brute-force references.
#include <Eigen/Geometry>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <sstream>

#include "core/error.h"
#include "data/bop.h"
#include "data/render.h"
#include "data/render_primitives.h"
#include "data/sensor_noise.h"
#include "geometry/camera.h"
#include "mesh_distance.h"
#include "testing.h"

using namespace g2l;
using namespace g2l::data;
using Catch::Contains;

using g2l::testing::point_triangle_distance;

namespace {

const geom::Intrinsics kYcb{1066.778, 1067.487, 312.9869, 241.3109, 640, 480};

double mesh_distance(const geom::Mesh& m, const Eigen::Vector3d& p) {
    double best = 1e30;
    for (int f = 0; f < m.faces.rows(); ++f) {
        const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)).cast<double>().transpose();
        const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1)).cast<double>().transpose();
        const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2)).cast<double>().transpose();
        best = std::min(best, point_triangle_distance(p, a, b, c));
    }
    return best;
}

geom::Pose make_pose(double ax, double ay, double az, Eigen::Vector3d t) {
    geom::Pose p;
    p.R = (Eigen::AngleAxisd(az, Eigen::Vector3d::UnitZ()) *
           Eigen::AngleAxisd(ay, Eigen::Vector3d::UnitY()) *
           Eigen::AngleAxisd(ax, Eigen::Vector3d::UnitX()))
              .toRotationMatrix();
    p.t = t;
    return p;
}

int64_t count_ids(const RenderOutput& out, int32_t id) {
    return std::count(out.instance.begin(), out.instance.end(), id);
}

}  // namespace

TEST_CASE("rendered depth back-projects onto the posed mesh within 1 mm", "[data][render]") {
    const geom::Mesh sphere = make_icosphere(70.0, 2);  // 320 triangles
    const geom::Mesh box = make_box(80, 50, 120);
    Renderer r(kYcb);
    RenderOutput out;
    struct Case { const geom::Mesh* mesh; geom::Pose pose; };
    const Case cases[] = {{&sphere, make_pose(0.3, -0.7, 1.1, {40, -30, 700})},
                          {&box, make_pose(0.5, 0.9, -0.4, {-60, 45, 1200})},
                          {&box, make_pose(-1.2, 0.2, 2.5, {150, 100, 450})}};
    for (const Case& c : cases) {
        r.render({RenderObject{c.mesh, c.pose, 1, {}}}, RenderOptions{}, out);
        std::vector<int> idx;
        const geom::Points pts =
            geom::depth_to_points(out.depth.data(), 640, 480, kYcb, {0, 0, 640, 480}, &idx);
        REQUIRE(pts.rows() > 2000);
        REQUIRE(pts.rows() == count_ids(out, 1));
        double worst = 0;
        for (Eigen::Index i = 0; i < pts.rows(); i += 3) {
            const Eigen::Vector3d xc = pts.row(i).cast<double>().transpose();
            const Eigen::Vector3d xm = c.pose.R.transpose() * (xc - c.pose.t);
            worst = std::max(worst, mesh_distance(*c.mesh, xm));
        }
        INFO("worst distance to the mesh: " << worst << " mm");
        CHECK(worst < 1.0);
        CHECK(worst < 0.1);  // the real error is float rounding + 1/16 px snapping
    }
}

TEST_CASE("a head-on cube's silhouette matches the analytic projection", "[data][render]") {
    // Cube centred on the optical axis: the silhouette is the projected front face, a
    // fx*s/zf by fy*s/zf rectangle centred on (cx, cy).
    geom::Intrinsics K = kYcb;
    K.cx = 320.3;
    K.cy = 240.7;
    const double s = 100, z = 1000, zf = z - s / 2;
    const geom::Mesh cube = make_box(s, s, s);
    Renderer r(K);
    RenderOutput out;
    geom::Pose pose;
    pose.t = {0, 0, z};
    r.render({RenderObject{&cube, pose, 3, {}}}, RenderOptions{}, out);
    const double half_u = K.fx * s / 2 / zf, half_v = K.fy * s / 2 / zf;
    // Exact count of pixel centres strictly inside (no centre lies on an edge here).
    const int64_t nu = int64_t(std::floor(K.cx + half_u) - std::ceil(K.cx - half_u) + 1);
    const int64_t nv = int64_t(std::floor(K.cy + half_v) - std::ceil(K.cy - half_v) + 1);
    const double area = 4 * half_u * half_v;
    CHECK(count_ids(out, 3) == nu * nv);
    CHECK(std::abs(double(count_ids(out, 3)) - area) / area < 0.02);
    CHECK(out.depth[240 * 640 + 320] == Approx(zf).margin(1e-3));
    CHECK(out.cos_view[240 * 640 + 320] == Approx(1.0).margin(1e-4));

    // Rotated 45 degrees about y: two faces visible, width grows to about s * sqrt(2).
    pose.R = make_pose(0, M_PI / 4, 0, {0, 0, 0}).R;
    r.render({RenderObject{&cube, pose, 3, {}}}, RenderOptions{}, out);
    int u_min = 640, u_max = -1;
    for (int u = 0; u < 640; ++u) {
        if (out.instance[240 * 640 + u] == 3) u_min = std::min(u_min, u), u_max = std::max(u_max, u);
    }
    // Silhouette spans x = +-s/sqrt(2) at the side edge at z - s/sqrt(2)... the near edge is
    // at depth z - s/sqrt(2); the extreme side edges at depth z, x = +-s/sqrt(2).
    const double w_expected = 2 * K.fx * (s / std::sqrt(2.0)) / z;
    CHECK(double(u_max - u_min + 1) == Approx(w_expected).margin(2.0));
    CHECK(out.depth[240 * 640 + 320] == Approx(z - s / std::sqrt(2.0)).margin(0.5));
}

TEST_CASE("shared edges leave no gaps: a tessellated square covers the exact pixel set",
          "[data][render]") {
    geom::Intrinsics K{500, 500, 100.37, 80.61, 200, 160};
    const geom::Mesh quad = make_quad(150.0, 16);  // 512 triangles, many shared edges
    Renderer r(K);
    RenderOutput out;
    geom::Pose pose;
    pose.R = make_pose(M_PI, 0, 0, {0, 0, 0}).R;  // flip so the front faces the camera
    pose.t = {3.1, -2.3, 800};
    for (const bool cull : {false, true}) {
        RenderOptions opt;
        opt.cull_back_faces = cull;
        r.render({RenderObject{&quad, pose, 1, {}}}, opt, out);
        const double h = 500 * 75.0 / 800;
        const double u0 = K.cx + 500 * 3.1 / 800 - h, u1 = K.cx + 500 * 3.1 / 800 + h;
        const double v0 = K.cy - 500 * 2.3 / 800 - h, v1 = K.cy - 500 * 2.3 / 800 + h;
        int64_t expected = 0, wrong = 0;
        for (int v = 0; v < 160; ++v) {
            for (int u = 0; u < 200; ++u) {
                const bool in = u > u0 && u < u1 && v > v0 && v < v1;
                expected += in;
                wrong += in != (out.instance[size_t(v) * 200 + u] == 1);
            }
        }
        CHECK(expected == 94 * 94);  // 2 * 46.9 px wide, no centre on an edge
        CHECK(wrong == 0);
        CHECK(r.last_triangle_count() == 512);
    }
    // Seen from behind it vanishes with culling on.
    pose.R.setIdentity();
    RenderOptions opt;
    opt.cull_back_faces = true;
    r.render({RenderObject{&quad, pose, 1, {}}}, opt, out);
    CHECK(count_ids(out, 1) == 0);
}

TEST_CASE("the nearer object wins the z-test", "[data][render]") {
    const geom::Mesh big = make_box(200, 200, 20), small = make_box(60, 60, 60);
    Renderer r(kYcb);
    RenderOutput out;
    geom::Pose far_pose, near_pose;
    far_pose.t = {0, 0, 1000};
    near_pose.t = {20, 10, 700};
    // Same result whatever the drawing order.
    for (const bool near_first : {false, true}) {
        std::vector<RenderObject> objs = {{&big, far_pose, 1, {}}, {&small, near_pose, 2, {}}};
        if (near_first) std::swap(objs[0], objs[1]);
        r.render(objs, RenderOptions{}, out);
        const size_t centre = size_t(std::lround(241.3109 + 1067.487 * 10 / 700)) * 640 +
                              size_t(std::lround(312.9869 + 1066.778 * 20 / 700));
        CHECK(out.instance[centre] == 2);
        CHECK(out.depth[centre] == Approx(670.0).margin(1e-3));
        CHECK(count_ids(out, 1) > 10000);
        CHECK(count_ids(out, 2) > 3000);
    }
}

TEST_CASE("near-plane clipping keeps the part in front of the camera", "[data][render]") {
    // Camera inside a box straddling z_near: every pixel sees the inside of the far face z = 40.
    const geom::Mesh box = make_box(100, 100, 100);
    Renderer r(kYcb);
    RenderOutput out;
    geom::Pose pose;
    pose.t = {0, 0, -10};  // spans z in [-60, 40]
    RenderOptions opt;
    opt.z_near = 5;
    r.render({RenderObject{&box, pose, 1, {}}}, opt, out);
    float zmin = 1e9f;
    for (float d : out.depth) {
        if (d > 0) zmin = std::min(zmin, d);
    }
    CHECK(zmin >= 5.0f - 1e-3f);
    CHECK(out.depth[241 * 640 + 313] == Approx(40.0).margin(1e-3));
    opt.cull_back_faces = true;  // from inside, every face is a back face
    r.render({RenderObject{&box, pose, 1, {}}}, opt, out);
    CHECK(count_ids(out, 1) == 0);

    // Box beside the camera (x in [10, 110], z in [-60, 40]): its face x = 10 crosses the near
    // plane and is seen only on the right of the image, at z = 10 fx / (u - cx).
    pose.t = {60, 0, -10};
    r.render({RenderObject{&box, pose, 1, {}}}, opt, out);
    const size_t row = 241 * 640;
    CHECK(out.depth[row + 600] == Approx(10 * 1066.778 / (600 - 312.9869)).epsilon(1e-4));
    CHECK(out.depth[row + 639] == Approx(10 * 1066.778 / (639 - 312.9869)).epsilon(1e-4));
    CHECK(out.depth[row + 575] == 0.0f);  // the ray passes beside the box (x < 10 at z = 40)
}

TEST_CASE("rendering is bit-identical for any thread count", "[data][render]") {
    const geom::Mesh sphere = make_icosphere(60.0, 4);
    geom::Mesh colored = make_box(90, 40, 70);
    colored.colors.resize(8, 3);
    for (int i = 0; i < 8; ++i) colored.colors.row(i) << uint8_t(30 * i), uint8_t(200 - 20 * i), 90;
    Renderer r(kYcb);
    std::vector<RenderObject> objs = {{&sphere, make_pose(0.1, 0.2, 0.3, {10, 0, 600}), 1, {}},
                                      {&colored, make_pose(1, 2, 3, {-40, 20, 550}), 2, {}}};
    RenderOutput ref, out;
    RenderOptions opt;
    opt.threads = 1;
    r.render(objs, opt, ref);
    for (const int t : {2, 3, 7}) {
        opt.threads = t;
        r.render(objs, opt, out);
        CHECK(out.depth == ref.depth);
        CHECK(out.rgb == ref.rgb);
        CHECK(out.instance == ref.instance);
        CHECK(out.cos_view == ref.cos_view);
    }
    // Vertex colours are interpolated: the box shows more than a handful of distinct colours.
    std::vector<int> seen;
    for (size_t i = 0; i < ref.instance.size(); ++i) {
        if (ref.instance[i] == 2) seen.push_back(ref.rgb[3 * i] * 65536 + ref.rgb[3 * i + 1] * 256);
    }
    std::sort(seen.begin(), seen.end());
    CHECK(std::unique(seen.begin(), seen.end()) - seen.begin() > 50);
}

TEST_CASE("renderer rejects bad input with the offending value", "[data][render]") {
    REQUIRE_THROWS_WITH(Renderer(geom::Intrinsics{0, 500, 10, 10, 64, 48}), Contains("fx=0"));
    REQUIRE_THROWS_WITH(Renderer(geom::Intrinsics{500, 500, 10, 10, 0, 48}), Contains("0 x 48"));
    Renderer r(kYcb);
    RenderOutput out;
    REQUIRE_THROWS_WITH(r.render({RenderObject{}}, RenderOptions{}, out),
                        Contains("object 0 has a null mesh"));
    geom::Mesh bad = make_box(10, 10, 10);
    bad.faces(5, 1) = 8;
    bad.path = "bad.ply";
    REQUIRE_THROWS_WITH(r.render({RenderObject{&bad, {}, 1, {}}}, RenderOptions{}, out),
                        Contains("face 5 uses vertex 8 of 8"));
    geom::Mesh no_faces = make_box(10, 10, 10);
    no_faces.faces.resize(0, 3);
    REQUIRE_THROWS_WITH(r.render({RenderObject{&no_faces, {}, 1, {}}}, RenderOptions{}, out),
                        Contains("has no faces"));
    geom::Pose nan_pose;
    nan_pose.t = {0, std::nan(""), 100};
    const geom::Mesh ok = make_box(10, 10, 10);
    REQUIRE_THROWS_WITH(r.render({RenderObject{&ok, nan_pose, 1, {}}}, RenderOptions{}, out),
                        Contains("non-finite pose"));
    RenderOptions opt;
    opt.z_near = -1;
    REQUIRE_THROWS_WITH(r.render({RenderObject{&ok, {}, 1, {}}}, opt, out),
                        Contains("z_near must be > 0 mm, got -1"));
    REQUIRE_THROWS_WITH(make_icosphere(-2, 1), Contains("-2"));
}

TEST_CASE("axial noise std follows sigma(z) = a + b z^2 within 10%", "[data][noise]") {
    SensorNoiseConfig cfg;
    cfg.holes_max = 0;
    cfg.edge_dropout_prob = 0;
    const int W = 256, H = 256;
    std::vector<float> scratch;
    for (const double z : {500.0, 1000.0, 2000.0, 3000.0}) {
        std::vector<float> d(size_t(W) * H, float(z));
        apply_sensor_noise(cfg, 42, W, H, nullptr, d.data(), scratch);
        double sum = 0, sum2 = 0;
        for (float v : d) sum += v - z, sum2 += (v - z) * (v - z);
        const double mean = sum / d.size(), sd = std::sqrt(sum2 / d.size() - mean * mean);
        const double expected = axial_sigma_mm(cfg, z);
        INFO("z " << z << " mm: std " << sd << " expected " << expected);
        CHECK(expected == Approx(0.5 + 2.0 * (z / 1000) * (z / 1000)));
        CHECK(std::abs(sd - expected) < 0.1 * expected);
        CHECK(std::abs(mean) < 0.05 * expected);
        // Quantised to the 0.1 mm depth_scale step.
        CHECK(std::abs(d[77] * 10 - std::round(d[77] * 10)) < 1e-3);
    }
}

TEST_CASE("noise drops grazing and edge pixels, is seeded and thread-independent",
          "[data][noise]") {
    const int W = 200, H = 100;
    std::vector<float> clean(size_t(W) * H), cosv(size_t(W) * H, 0.9f);
    for (int v = 0; v < H; ++v) {
        for (int u = 0; u < W; ++u) clean[size_t(v) * W + u] = u < 100 ? 800.0f : 1200.0f;
    }
    for (int v = 0; v < H; ++v) cosv[size_t(v) * W + 150] = 0.05f;  // a grazing column
    SensorNoiseConfig cfg;
    cfg.holes_max = 0;
    cfg.edge_dropout_prob = 0.5;
    std::vector<float> scratch, a = clean, b = clean, c = clean;
    apply_sensor_noise(cfg, 7, W, H, cosv.data(), a.data(), scratch, 1);
    apply_sensor_noise(cfg, 7, W, H, cosv.data(), b.data(), scratch, 2);
    apply_sensor_noise(cfg, 8, W, H, cosv.data(), c.data(), scratch, 2);
    CHECK(a == b);
    CHECK(a != c);
    int dropped_edge = 0, dropped_inner = 0, dropped_grazing = 0;
    for (int v = 0; v < H; ++v) {
        dropped_edge += (a[size_t(v) * W + 99] == 0) + (a[size_t(v) * W + 100] == 0);
        dropped_inner += a[size_t(v) * W + 50] == 0;
        dropped_grazing += a[size_t(v) * W + 150] == 0;
    }
    CHECK(dropped_grazing == H);
    CHECK(dropped_inner == 0);
    CHECK(dropped_edge > 70);   // expected 100 of 200 (p = 0.5)
    CHECK(dropped_edge < 130);

    cfg.holes_min = cfg.holes_max = 2;
    cfg.hole_radius_min_px = cfg.hole_radius_max_px = 5;
    cfg.edge_dropout_prob = 0;
    std::vector<float> h = clean;
    apply_sensor_noise(cfg, 9, W, H, nullptr, h.data(), scratch);
    const auto zeros = std::count(h.begin(), h.end(), 0.0f);
    CHECK(zeros > 60);   // two discs of radius 5 (~81 px each), possibly overlapping or clipped
    CHECK(zeros <= 2 * 121);

    SensorNoiseConfig bad;
    bad.edge_dropout_prob = 1.5;
    REQUIRE_THROWS_WITH(apply_sensor_noise(bad, 1, W, H, nullptr, h.data(), scratch),
                        Contains("edge_dropout_prob must be in [0, 1], got 1.5"));
    bad = SensorNoiseConfig{};
    bad.holes_min = 4;
    REQUIRE_THROWS_WITH(validate(bad), Contains("holes_min <= holes_max, got 4 and 3"));
    REQUIRE_THROWS_WITH(apply_sensor_noise(cfg, 1, W, H, nullptr, nullptr, scratch),
                        Contains("null depth"));
}

TEST_CASE("default noise model is close to the real YCB-Video depth noise", "[data][noise][real]") {
    // Residual of the real Asus Xtion depth to the model rendered at the GT pose, on pixels both
    // mark as the object. A per-instance median removes pose/calibration offsets; what remains
    // (robust std = 1.4826 * MAD) bounds the sensor noise from above (it still holds small pose
    // and model errors).
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) {
        g2l::testing::skip_without_shared_data("real YCB-V depth-noise comparison");
        return;
    }
    const BopDataset ds = open_bop(*shared + "/ycbv", "train_real");
    REQUIRE(!ds.frames().empty());
    std::vector<double> resid, second, zs;
    RenderOutput out;
    for (size_t fi = 0; fi < ds.frames().size(); fi += 3) {
        const Frame& fr = ds.frames()[fi];
        Renderer r(fr.K);
        std::vector<RenderObject> objs;
        for (size_t k = 0; k < fr.instances.size(); ++k) {
            const Instance& in = fr.instances[k];
            objs.push_back({&ds.load_model_mesh(in.obj_id), in.pose, int32_t(k + 1), {}});
        }
        r.render(objs, RenderOptions{}, out);
        int w = 0, h = 0;
        const std::vector<float> real = ds.load_depth_mm(fr, &w, &h);
        for (size_t k = 0; k < fr.instances.size(); ++k) {
            const Image m = ds.load_mask(fr, fr.instances[k]);
            std::vector<double> d;
            std::vector<double> dz;
            for (int v = 1; v + 1 < h; ++v) {
                for (int u = 1; u + 1 < w; ++u) {
                    const size_t i = size_t(v) * w + u;
                    if (!m.data[i] || out.instance[i] != int32_t(k + 1) || real[i] <= 0) continue;
                    if (std::abs(real[i] - out.depth[i]) > 30) continue;
                    d.push_back(real[i] - out.depth[i]);
                    dz.push_back(out.depth[i]);
                    if (real[i - 1] > 0 && real[i + 1] > 0 && m.data[i - 1] && m.data[i + 1]) {
                        second.push_back(real[i - 1] - 2 * real[i] + real[i + 1]);
                    }
                }
            }
            if (d.size() < 500) continue;
            std::vector<double> s = d;
            std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
            const double med = s[s.size() / 2];
            for (size_t j = 0; j < d.size(); ++j) {
                resid.push_back(std::abs(d[j] - med));
                zs.push_back(dz[j]);
            }
        }
    }
    REQUIRE(resid.size() > 10000);
    auto robust_std = [](std::vector<double> a) {
        for (double& x : a) x = std::abs(x);
        std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
        return 1.4826 * a[a.size() / 2];
    };
    const double sigma_resid = robust_std(resid);
    int64_t flat = 0;  // real depth is smooth/quantised: many exact zero second differences
    for (double x : second) flat += x == 0;
    double zmean = 0;
    for (double z : zs) zmean += z / double(zs.size());
    const SensorNoiseConfig def;
    std::ostringstream bins;
    for (const double lo : {500.0, 700.0, 850.0, 1000.0}) {
        std::vector<double> b;
        double zb = 0;
        for (size_t j = 0; j < zs.size(); ++j) {
            if (zs[j] >= lo && zs[j] < lo + (lo < 1000 ? 150 : 1000)) b.push_back(resid[j]), zb += zs[j];
        }
        if (b.size() < 2000) continue;
        zb /= double(b.size());
        bins << "\n  z ~ " << zb << " mm: real " << robust_std(b) << " mm vs model "
             << axial_sigma_mm(def, zb) << " mm (" << b.size() << " px)";
    }
    const double model = axial_sigma_mm(def, zmean);
    WARN("YCB-V real depth: " << resid.size() << " pixels, mean z " << zmean
                              << " mm: residual-to-model robust std " << sigma_resid
                              << " mm; default model sigma(z) " << model << " mm; "
                              << 100.0 * double(flat) / double(second.size())
                              << "% of horizontal second differences are exactly 0"
                              << bins.str());
    // The residual also holds GT-pose and model errors, so it bounds the sensor noise from above;
    // the default must not exceed it, nor be far below it.
    CHECK(model <= sigma_resid * 1.05);
    CHECK(model >= sigma_resid * 0.6);
}
