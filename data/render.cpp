// SPDX-License-Identifier: MIT
#include "data/render.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "core/error.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace g2l::data {
namespace {

constexpr int kSubBits = 4;                 // 1/16 pixel fixed point
constexpr int64_t kSub = int64_t(1) << kSubBits;
constexpr int kBandRows = 16;               // rows per parallel work item

// floor(a / 2^kSubBits) and ceil(...) for negative values too.
int64_t floor_sub(int64_t a) { return a >= 0 ? a / kSub : -((-a + kSub - 1) / kSub); }
int64_t ceil_sub(int64_t a) { return -floor_sub(-a); }

// A clip-space polygon vertex: camera-frame position and lit colour.
struct ClipVertex {
    Eigen::Vector3f p;
    Eigen::Vector3f c;
};

// Plane a.x + b.y + c.z + d >= 0 keeps the inside. The near plane and a guard band around the
// image (planes through the camera centre) bound the projected coordinates so the fixed-point
// edge functions cannot overflow.
struct ClipPlane {
    float a, b, c, d;
    float eval(const Eigen::Vector3f& p) const { return a * p.x() + b * p.y() + c * p.z() + d; }
};

// Sutherland-Hodgman against one plane; in has n vertices, out gets at most n + 1.
int clip_polygon(const ClipVertex* in, int n, const ClipPlane& pl, ClipVertex* out) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const ClipVertex& a = in[i];
        const ClipVertex& b = in[(i + 1) % n];
        const float da = pl.eval(a.p), db = pl.eval(b.p);
        if (da >= 0) out[m++] = a;
        if ((da >= 0) != (db >= 0)) {
            const float s = da / (da - db);
            out[m++] = {a.p + s * (b.p - a.p), a.c + s * (b.c - a.c)};
        }
    }
    return m;
}

// Edge function of a -> b at p (all in 1/16 px); > 0 on the inner side of a positive triangle.
inline int64_t edge(int64_t ax, int64_t ay, int64_t bx, int64_t by, int64_t px, int64_t py) {
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

// One triangle of a clipped polygon on the screen, in 1/16-pixel fixed point, wound
// counter-clockwise, with the pixel rows and columns it may cover; false when it covers no pixel
// centre (or has no area).
bool screen_triangle(const ClipVertex* const v[3], const geom::Intrinsics& K,
                     const Eigen::Vector3f& n_view, int32_t instance_id, Renderer::ScreenTri* out) {
    const float fx = float(K.fx), fy = float(K.fy), cx = float(K.cx), cy = float(K.cy);
    Renderer::ScreenTri& st = *out;
    for (int j = 0; j < 3; ++j) {
        const float iz = 1.0f / v[j]->p.z();
        st.x[j] = std::llround(double(fx * v[j]->p.x() * iz + cx) * kSub);
        st.y[j] = std::llround(double(fy * v[j]->p.y() * iz + cy) * kSub);
        st.inv_z[j] = iz;
        for (int c = 0; c < 3; ++c) st.col[j][c] = v[j]->c[c];
    }
    st.area2 = edge(st.x[0], st.y[0], st.x[1], st.y[1], st.x[2], st.y[2]);
    if (st.area2 == 0) return false;
    if (st.area2 < 0) {  // make the screen winding positive
        std::swap(st.x[1], st.x[2]);
        std::swap(st.y[1], st.y[2]);
        std::swap(st.inv_z[1], st.inv_z[2]);
        for (int c = 0; c < 3; ++c) std::swap(st.col[1][c], st.col[2][c]);
        st.area2 = -st.area2;
    }
    const int64_t x_lo = std::min({st.x[0], st.x[1], st.x[2]});
    const int64_t x_hi = std::max({st.x[0], st.x[1], st.x[2]});
    const int64_t y_lo = std::min({st.y[0], st.y[1], st.y[2]});
    const int64_t y_hi = std::max({st.y[0], st.y[1], st.y[2]});
    st.xmin = int32_t(std::max<int64_t>(0, ceil_sub(x_lo)));
    st.xmax = int32_t(std::min<int64_t>(K.width - 1, floor_sub(x_hi)));
    st.ymin = int32_t(std::max<int64_t>(0, ceil_sub(y_lo)));
    st.ymax = int32_t(std::min<int64_t>(K.height - 1, floor_sub(y_hi)));
    if (st.xmin > st.xmax || st.ymin > st.ymax) return false;  // covers no pixel centre
    for (int c = 0; c < 3; ++c) st.n[c] = n_view[c];
    st.instance_id = instance_id;
    return true;
}


// Top-left fill rule for triangles with positive edge() area (screen y points down): pixels
// exactly on a top edge (horizontal, going right) or a left edge (going up) belong to the
// triangle, pixels on other edges do not. Returns the bias subtracted from the edge value.
inline int64_t fill_bias(int64_t ax, int64_t ay, int64_t bx, int64_t by) {
    const int64_t dx = bx - ax, dy = by - ay;
    const bool top_left = (dy == 0 && dx > 0) || dy < 0;
    return top_left ? 0 : 1;
}

}  // namespace

Renderer::Renderer(const geom::Intrinsics& K) : K_(K) {
    G2L_CHECK(K.width >= 1 && K.width <= 16384 && K.height >= 1 && K.height <= 16384,
              "Renderer: image size must be in [1, 16384], got ", K.width, " x ", K.height);
    G2L_CHECK(K.fx > 0 && K.fy > 0 && std::isfinite(K.cx) && std::isfinite(K.cy),
              "Renderer: need fx, fy > 0 and finite cx, cy; got fx=", K.fx, " fy=", K.fy,
              " cx=", K.cx, " cy=", K.cy);
}

void Renderer::setup_object(const RenderObject& obj, int index, const RenderOptions& opt) {
    G2L_CHECK(obj.mesh != nullptr, "Renderer::render: object ", index, " has a null mesh");
    const geom::Mesh& mesh = *obj.mesh;
    const int64_t nv = mesh.vertices.rows();
    G2L_CHECK(mesh.faces.rows() > 0, "Renderer::render: object ", index, " mesh '", mesh.path,
              "' has no faces (", nv, " vertices)");
    G2L_CHECK(mesh.colors.rows() == 0 || mesh.colors.rows() == nv, "Renderer::render: object ",
              index, " mesh '", mesh.path, "' has ", mesh.colors.rows(), " colours for ", nv,
              " vertices");
    const bool has_normals = mesh.normals.rows() == nv && nv > 0;
    G2L_CHECK(obj.pose.R.allFinite() && obj.pose.t.allFinite(), "Renderer::render: object ",
              index, " has a non-finite pose, t = (", obj.pose.t.transpose(), ")");

    // Pose all vertices once (double pose, float storage: sub-micrometre error at 2 m).
    const Eigen::Matrix3f R = obj.pose.R.cast<float>();
    const Eigen::Vector3f t = obj.pose.t.cast<float>();
    cam_vertices_.resize(static_cast<size_t>(nv));
    for (int64_t i = 0; i < nv; ++i) {
        cam_vertices_[i] = R * mesh.vertices.row(i).transpose() + t;
    }

    const float fx = float(K_.fx), fy = float(K_.fy), cx = float(K_.cx), cy = float(K_.cy);
    const float guard = float(std::max(K_.width, K_.height));
    const float umin = -guard, umax = float(K_.width) + guard;
    const float vmin = -guard, vmax = float(K_.height) + guard;
    const ClipPlane planes[5] = {
        {0, 0, 1, -opt.z_near},          // z >= z_near
        {fx, 0, cx - umin, 0},           // u >= umin
        {-fx, 0, umax - cx, 0},          // u <= umax
        {0, fy, cy - vmin, 0},           // v >= vmin
        {0, -fy, vmax - cy, 0},          // v <= vmax
    };
    const Eigen::Vector3f base_color(obj.default_color[0], obj.default_color[1],
                                     obj.default_color[2]);
    const Eigen::Vector3f light = opt.light.direction.normalized();

    for (int64_t f = 0; f < mesh.faces.rows(); ++f) {
        int32_t idx[3];
        for (int k = 0; k < 3; ++k) {
            idx[k] = mesh.faces(f, k);
            G2L_CHECK(idx[k] >= 0 && idx[k] < nv, "Renderer::render: object ", index, " mesh '",
                      mesh.path, "' face ", f, " uses vertex ", idx[k], " of ", nv);
        }
        const Eigen::Vector3f& p0 = cam_vertices_[idx[0]];
        const Eigen::Vector3f& p1 = cam_vertices_[idx[1]];
        const Eigen::Vector3f& p2 = cam_vertices_[idx[2]];
        Eigen::Vector3f n = (p1 - p0).cross(p2 - p0);
        const float nn = n.norm();
        if (!(nn > 0)) continue;  // degenerate triangle
        n /= nn;
        const bool back = n.dot(p0) > 0;  // front side (CCW in model) faces away from camera
        if (back && opt.cull_back_faces) continue;
        const Eigen::Vector3f n_view = back ? Eigen::Vector3f(-n) : n;  // side we look at

        ClipVertex poly[2][12];
        for (int k = 0; k < 3; ++k) {
            Eigen::Vector3f nl = n_view;
            if (has_normals) {
                nl = R * mesh.normals.row(idx[k]).transpose();
                if (nl.dot(n_view) < 0) nl = -nl;
                const float len = nl.norm();
                nl = len > 0 ? Eigen::Vector3f(nl / len) : n_view;
            }
            const float lit = std::min(1.5f, opt.light.ambient +
                                                  opt.light.diffuse * std::max(0.0f, nl.dot(light)));
            Eigen::Vector3f c = base_color;
            if (mesh.colors.rows() > 0) {
                c = mesh.colors.row(idx[k]).transpose().cast<float>();
            }
            poly[0][k] = {cam_vertices_[idx[k]], c * lit};
        }
        int n_poly = 3, cur = 0;
        for (const ClipPlane& pl : planes) {
            const bool all_in = pl.eval(poly[cur][0].p) >= 0 && pl.eval(poly[cur][1].p) >= 0 &&
                                pl.eval(poly[cur][2].p) >= 0 && n_poly == 3;
            if (all_in) continue;
            n_poly = clip_polygon(poly[cur], n_poly, pl, poly[1 - cur]);
            cur = 1 - cur;
            if (n_poly < 3) break;
        }
        if (n_poly < 3) continue;

        // Fan-triangulate the (convex) clipped polygon.
        for (int k = 1; k + 1 < n_poly; ++k) {
            const ClipVertex* v[3] = {&poly[cur][0], &poly[cur][k], &poly[cur][k + 1]};
            Renderer::ScreenTri st;
            if (screen_triangle(v, K_, n_view, obj.instance_id, &st)) tris_.push_back(st);
        }
    }
}

void Renderer::render(const std::vector<RenderObject>& objects, const RenderOptions& opt,
                      RenderOutput& out) {
    G2L_CHECK(opt.z_near > 0 && std::isfinite(opt.z_near),
              "Renderer::render: z_near must be > 0 mm, got ", opt.z_near);
    G2L_CHECK(opt.light.direction.allFinite() && opt.light.direction.norm() > 0,
              "Renderer::render: light direction must be finite and non-zero");
    const int W = K_.width, H = K_.height;
    const size_t npix = size_t(W) * size_t(H);
    out.width = W;
    out.height = H;
    // Sized here, cleared per band inside the parallel loop (while the rows are in cache).
    out.depth.resize(npix);  // holds 1/z while rasterising (larger = nearer), 0 = empty
    out.instance.resize(npix);
    out.cos_view.resize(npix);
    out.rgb.resize(npix * 3);
    tri_index_.resize(npix);

    tris_.clear();
    for (size_t i = 0; i < objects.size(); ++i) setup_object(objects[i], int(i), opt);

    // Bin triangles by row band (in triangle order, which fixes the depth-tie winner).
    const int n_bands = (H + kBandRows - 1) / kBandRows;
    bins_.resize(size_t(n_bands));
    for (auto& b : bins_) b.clear();
    for (size_t i = 0; i < tris_.size(); ++i) {
        for (int b = tris_[i].ymin / kBandRows; b <= tris_[i].ymax / kBandRows; ++b) {
            bins_[size_t(b)].push_back(int32_t(i));
        }
    }

    // Bands write disjoint rows, so the schedule cannot change the result.
#ifdef _OPENMP
    const int nt = opt.threads > 0 ? opt.threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
#endif
    for (int b = 0; b < n_bands; ++b) {
        rasterize_band(b, out);
        shade_band(b, opt, out);
    }
}

void Renderer::rasterize_band(int band, RenderOutput& out) {
    const int W = K_.width;
    const int r0 = band * kBandRows, r1 = std::min(K_.height, r0 + kBandRows) - 1;
    float* zbuf = out.depth.data();  // 1/z, 0 = empty
    int32_t* tri_of = tri_index_.data();
    const size_t i0 = size_t(r0) * W, i1 = size_t(r1 + 1) * W;
    std::fill(zbuf + i0, zbuf + i1, 0.0f);
    std::fill(tri_of + i0, tri_of + i1, -1);
    for (const int32_t ti : bins_[size_t(band)]) {
        const ScreenTri& t = tris_[size_t(ti)];
        const int y0 = std::max<int>(t.ymin, r0), y1 = std::min<int>(t.ymax, r1);
        if (y0 > y1) continue;
        // Edge k is opposite vertex k; its value is vertex k's barycentric weight * area2.
        const int64_t b0 = fill_bias(t.x[1], t.y[1], t.x[2], t.y[2]);
        const int64_t b1 = fill_bias(t.x[2], t.y[2], t.x[0], t.y[0]);
        const int64_t b2 = fill_bias(t.x[0], t.y[0], t.x[1], t.y[1]);
        const int64_t sx0 = -(t.y[2] - t.y[1]) * kSub, sx1 = -(t.y[0] - t.y[2]) * kSub;
        const int64_t sx2 = -(t.y[1] - t.y[0]) * kSub;
        const float inv_area = 1.0f / float(t.area2);
        const float dz1 = t.inv_z[1] - t.inv_z[0], dz2 = t.inv_z[2] - t.inv_z[0];
        for (int v = y0; v <= y1; ++v) {
            const int64_t px = int64_t(t.xmin) * kSub, py = int64_t(v) * kSub;
            int64_t e0 = edge(t.x[1], t.y[1], t.x[2], t.y[2], px, py) - b0;
            int64_t e1 = edge(t.x[2], t.y[2], t.x[0], t.y[0], px, py) - b1;
            int64_t e2 = edge(t.x[0], t.y[0], t.x[1], t.y[1], px, py) - b2;
            float* zrow = zbuf + size_t(v) * W;
            int32_t* trow = tri_of + size_t(v) * W;
            for (int u = t.xmin; u <= t.xmax; ++u, e0 += sx0, e1 += sx1, e2 += sx2) {
                if ((e0 | e1 | e2) < 0) continue;
                // Unbiased weights of vertices 1 and 2 (the bias only decides edge ownership).
                const float w1 = float(e1 + b1) * inv_area, w2 = float(e2 + b2) * inv_area;
                const float iz = t.inv_z[0] + w1 * dz1 + w2 * dz2;
                if (iz > zrow[u]) {
                    zrow[u] = iz;
                    trow[u] = ti;
                }
            }
        }
    }
}

void Renderer::shade_band(int band, const RenderOptions& opt, RenderOutput& out) const {
    const int W = K_.width;
    const int r0 = band * kBandRows, r1 = std::min(K_.height, r0 + kBandRows);
    const float ifx = float(1.0 / K_.fx), ify = float(1.0 / K_.fy);
    const float cx = float(K_.cx), cy = float(K_.cy);
    for (int v = r0; v < r1; ++v) {
        for (int u = 0; u < W; ++u) {
            const size_t i = size_t(v) * W + u;
            uint8_t* rgb = &out.rgb[3 * i];
            const int32_t ti = tri_index_[i];
            if (ti < 0) {
                out.instance[i] = 0;
                if (opt.shade) {
                    rgb[0] = opt.background[0];
                    rgb[1] = opt.background[1];
                    rgb[2] = opt.background[2];
                    out.cos_view[i] = 0.0f;
                }
                continue;
            }
            const ScreenTri& t = tris_[size_t(ti)];
            const float iz = out.depth[i];
            const float z = 1.0f / iz;
            out.depth[i] = z;
            out.instance[i] = t.instance_id;
            if (!opt.shade) continue;
            const int64_t px = int64_t(u) * kSub, py = int64_t(v) * kSub;
            const float inv_area = 1.0f / float(t.area2);
            const float w0 = float(edge(t.x[1], t.y[1], t.x[2], t.y[2], px, py)) * inv_area;
            const float w1 = float(edge(t.x[2], t.y[2], t.x[0], t.y[0], px, py)) * inv_area;
            const float w2 = float(edge(t.x[0], t.y[0], t.x[1], t.y[1], px, py)) * inv_area;
            // Perspective-correct attribute weights: screen weights scaled by 1/z_k, renormalised.
            const float p0 = w0 * t.inv_z[0] * z, p1 = w1 * t.inv_z[1] * z,
                        p2 = w2 * t.inv_z[2] * z;
            for (int c = 0; c < 3; ++c) {
                const float col = p0 * t.col[0][c] + p1 * t.col[1][c] + p2 * t.col[2][c];
                rgb[c] = uint8_t(std::clamp(col + 0.5f, 0.0f, 255.0f));
            }
            const float dx = (float(u) - cx) * ifx, dy = (float(v) - cy) * ify;
            const float dot = t.n[0] * dx + t.n[1] * dy + t.n[2];
            out.cos_view[i] = std::fabs(dot) / std::sqrt(dx * dx + dy * dy + 1.0f);
        }
    }
}

}  // namespace g2l::data
