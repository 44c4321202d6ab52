// SPDX-License-Identifier: MIT
// CPU z-buffer rasterizer for synthetic RGB-D training data.
//
// Conventions (the same as geometry/camera.h back-projection): the camera looks along +z, image
// u grows with x and v with y, and pixel (u, v) has its centre at the point (u, v) of the K
// convention u = fx * X / Z + cx, so X = (u - cx) * Z / fx back-projects it. Depth is the camera
// z of the nearest surface in millimetres (not the ray length); 0 means no surface.
//
// Method: vertices are posed into the camera frame, every triangle is clipped against the near
// plane z = z_near and a guard band around the image, snapped to 1/16-pixel fixed point and
// rasterised with exact integer edge functions and the top-left fill rule (no pixel is covered
// twice by two triangles sharing an edge). 1/z is interpolated linearly in screen space, which
// makes depth and colour perspective-correct. The image is split into row bands processed in
// parallel (OpenMP); each band walks the triangles in the same order and keeps the first
// triangle on depth ties, so the output is bit-identical for any thread count.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "geometry/types.h"

namespace g2l::data {

/// One mesh instance to draw. The mesh is borrowed (must outlive the render call).
struct RenderObject {
    const geom::Mesh* mesh = nullptr;  ///< vertices in model frame (mm); faces required
    geom::Pose pose;                   ///< x_cam = R * x_model + t (mm)
    int32_t instance_id = 0;           ///< written to the instance image (0 = background/clutter)
    /// Colour used for every vertex when the mesh has no per-vertex colours (uniform grey).
    std::array<uint8_t, 3> default_color{{170, 170, 170}};
};

/// Lambertian light: intensity = ambient + diffuse * max(0, n . l), clamped to [0, 1.5].
struct Light {
    /// Unit vector from the surface towards the light, camera frame. The default comes from the
    /// camera side, slightly above (camera y points down).
    Eigen::Vector3f direction{0.0f, -0.447f, -0.894f};
    float ambient = 0.35f;
    float diffuse = 0.65f;
};

/// Rasterizer settings.
struct RenderOptions {
    float z_near = 10.0f;          ///< near clipping plane, mm (> 0)
    bool cull_back_faces = false;  ///< drop triangles whose front side faces away from the camera
    Light light;
    /// Colour of pixels without any surface (the scene code may paint its own background).
    std::array<uint8_t, 3> background{{0, 0, 0}};
    int threads = 0;  ///< OpenMP threads for this call; 0 = the OpenMP default
    /// false: only depth and instance are produced (rgb and cos_view are left unspecified);
    /// used for the cheap per-object silhouette renders of the scene generator.
    bool shade = true;
};

/// Rendered buffers, all H x W row-major (index v * width + u). Re-used across calls: the
/// renderer only reallocates when the image size grows.
struct RenderOutput {
    int width = 0, height = 0;
    std::vector<float> depth;       ///< camera z of the surface, mm; 0 = no surface
    std::vector<uint8_t> rgb;       ///< H x W x 3, R G B
    std::vector<int32_t> instance;  ///< RenderObject::instance_id of the visible surface; 0 = none
    /// |cos| of the angle between the surface normal and the viewing ray (0 = grazing, 1 =
    /// head-on); 0 where there is no surface. Used by the sensor-noise model.
    std::vector<float> cos_view;
};

/// Fixed-intrinsics rasterizer holding the per-frame scratch memory (allocation-free in the
/// steady state). Not thread-safe: use one Renderer per thread; it parallelises internally.
class Renderer {
public:
    /// Throws g2l::Error when width/height are not in [1, 16384] or fx/fy are not > 0.
    explicit Renderer(const geom::Intrinsics& K);

    const geom::Intrinsics& intrinsics() const { return K_; }

    /// Draws `objects` into `out` (cleared first). Throws g2l::Error naming the object index
    /// for a null mesh, a mesh without faces, a face index out of range, per-vertex colours whose
    /// count differs from the vertex count, a non-finite pose, or z_near <= 0.
    void render(const std::vector<RenderObject>& objects, const RenderOptions& opt,
                RenderOutput& out);

    /// Number of triangles drawn by the last render() after culling and clipping.
    int64_t last_triangle_count() const { return static_cast<int64_t>(tris_.size()); }

    /// Screen-space triangle after clipping; public only so the .cpp helpers can see it.
    struct ScreenTri {
        int64_t x[3], y[3];      ///< vertex positions in 1/16 pixel, counter-clockwise on screen
        float inv_z[3];          ///< 1 / camera z of each vertex
        float col[3][3];         ///< vertex colour (0..255) already multiplied by the light
        float n[3];              ///< unit face normal, camera frame
        int32_t ymin, ymax;      ///< pixel rows touched (inclusive)
        int32_t xmin, xmax;      ///< pixel columns touched (inclusive)
        int64_t area2;           ///< twice the signed area in (1/16 px)^2, > 0
        int32_t instance_id;
    };

private:
    void setup_object(const RenderObject& obj, int index, const RenderOptions& opt);
    void rasterize_band(int band, RenderOutput& out);
    void shade_band(int band, const RenderOptions& opt, RenderOutput& out) const;

    geom::Intrinsics K_;
    std::vector<ScreenTri> tris_;
    std::vector<Eigen::Vector3f> cam_vertices_;  ///< scratch: posed vertices of one object
    std::vector<Eigen::Vector3f> vert_colors_;   ///< scratch: lit vertex colours of one object
    std::vector<int32_t> tri_index_;             ///< per pixel: winning triangle, -1 = none
    std::vector<std::vector<int32_t>> bins_;     ///< per row band: indices into tris_, in order
};

}  // namespace g2l::data
