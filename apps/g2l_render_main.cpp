// SPDX-License-Identifier: MIT
// g2l_render: renders a synthetic BOP dataset (depth, RGB, masks, GT poses) from object meshes.
// Exit codes: 0 success, 1 runtime error (bad file, bad config), 2 usage error.
#include <unistd.h>

#include <CLI/CLI.hpp>

#include "core/cli.h"
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "data/bop_writer.h"
#include "data/render_primitives.h"
#include "data/scene.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace fs = std::filesystem;
using namespace g2l;
using Clock = std::chrono::steady_clock;

namespace {

struct LoadedModel {
    int obj_id;
    std::unique_ptr<geom::Mesh> mesh;
    std::string symmetries;  // declared in the models_info.json beside the mesh (data/scene.h)
    std::string name;        // the file's name without extension
};

// --models takes a folder (every obj_*.ply / *.ply in it) or a list of mesh files. Files without
// an obj_NNNNNN name get the smallest free ids in the order given (data::mesh_file_ids),
// printed and written to <out>/obj_names.json.
std::vector<LoadedModel> load_models(const std::vector<std::string>& args) {
    std::vector<std::string> files;
    for (const std::string& a : args) {
        G2L_CHECK(fs::exists(a), "--models: '", a, "' does not exist");
        if (fs::is_directory(a)) {
            std::vector<std::string> found;
            for (const auto& e : fs::directory_iterator(a)) {
                const std::string ext = e.path().extension().string();
                if (e.is_regular_file() && (ext == ".ply" || ext == ".PLY" || ext == ".obj")) {
                    found.push_back(e.path().string());
                }
            }
            std::sort(found.begin(), found.end());
            G2L_CHECK(!found.empty(), "--models: folder '", a, "' holds no .ply/.obj mesh");
            files.insert(files.end(), found.begin(), found.end());
        } else {
            files.push_back(a);
        }
    }
    std::vector<LoadedModel> out;
    const std::vector<int> ids = data::mesh_file_ids(files);
    for (size_t i = 0; i < files.size(); ++i) {
        const int id = ids[i];
        // The symmetries the models_info.json beside the mesh declares travel with it.
        const std::string info = (fs::path(files[i]).parent_path() / "models_info.json").string();
        auto mesh = std::make_unique<geom::Mesh>(geom::load_mesh(files[i]));
        // Millimetres, and the diameter the models_info.json beside it declares (if any).
        std::map<int, geom::ModelInfo> declared;
        if (fs::exists(info)) declared = geom::load_models_info_json(info);
        geom::check_mesh_units(*mesh, declared.count(id) ? &declared.at(id) : nullptr, "'" + info + "'");
        out.push_back({id, std::move(mesh), data::read_symmetries(info, id),
                       fs::path(files[i]).stem().string()});
    }
    return out;
}

std::vector<int> parse_ids(const std::string& s) {
    std::vector<int> ids;
    std::stringstream ss(s);
    std::string tok;
    while (std::getline(ss, tok, ',')) {
        G2L_CHECK(!tok.empty() && tok.find_first_not_of("0123456789") == std::string::npos,
                  "--objects: '", tok, "' is not a positive integer (in '", s, "')");
        ids.push_back(std::stoi(tok));
    }
    G2L_CHECK(!ids.empty(), "--objects: empty object list");
    return ids;
}

void progress(int64_t done, int64_t total, double secs, bool tty) {
    const double fps = secs > 0 ? double(done) / secs : 0.0;
    const double eta = fps > 0 ? double(total - done) / fps : 0.0;
    if (tty) {
        const int width = 30, fill = int(width * done / std::max<int64_t>(total, 1));
        std::fprintf(stderr, "\r[%s%s] %lld/%lld  %.1f fps  ETA %02d:%02d  ",
                     std::string(size_t(fill), '=').c_str(),
                     std::string(size_t(width - fill), ' ').c_str(), (long long)done,
                     (long long)total, fps, int(eta) / 60, int(eta) % 60);
        if (done == total) std::fprintf(stderr, "\n");
    } else {
        std::fprintf(stderr, "rendered %lld/%lld frames, %.1f fps, ETA %.0f s\n",
                     (long long)done, (long long)total, fps, eta);
    }
}

// Times the rasterizer alone and the whole per-frame pipeline (scene sampling, rendering, solo
// renders for the GT, sensor noise) on a ~20k-triangle 640 x 480 scene.
int run_bench(std::vector<LoadedModel> models, int frames, int threads, uint64_t seed) {
    if (models.empty()) {  // 4 icospheres of 5120 triangles + the support plane (128)
        for (int k = 0; k < 4; ++k) {
            models.push_back({k + 1, std::make_unique<geom::Mesh>(
                                         data::make_icosphere(40.0 + 15.0 * k, 4)), "", "sphere"});
        }
    }
    data::SceneConfig cfg;
    cfg.seed = seed;
    cfg.targets_min = cfg.targets_max = int(models.size());
    cfg.support_plane_prob = 1.0;
    std::vector<data::SceneModel> sm;
    int64_t tris = 0;
    for (const LoadedModel& m : models) {
        sm.push_back({m.obj_id, m.mesh.get()});
        tris += m.mesh->faces.rows();
    }
    data::SceneGenerator gen(cfg, sm);
    data::RenderedFrame frame;
    gen.render_frame(0, frame, threads);  // warm-up (allocations)

    // Rasterizer only: the same objects at the poses of the generated frames.
    data::Renderer renderer(cfg.camera);
    data::RenderOptions opt;
    opt.threads = threads;
    data::RenderOutput out;
    std::vector<std::vector<data::RenderObject>> scenes;
    for (int f = 0; f < 8; ++f) {
        gen.render_frame(f, frame, threads);
        std::vector<data::RenderObject> objs;
        for (size_t k = 0; k < frame.instances.size(); ++k) {
            const auto it = std::find_if(models.begin(), models.end(), [&](const LoadedModel& m) {
                return m.obj_id == frame.instances[k].obj_id;
            });
            objs.push_back({it->mesh.get(), frame.instances[k].pose, int32_t(k + 1), {}});
        }
        scenes.push_back(objs);
    }
    renderer.render(scenes[0], opt, out);
    auto t0 = Clock::now();
    for (int f = 0; f < frames; ++f) renderer.render(scenes[size_t(f) % scenes.size()], opt, out);
    const double raster_s = std::chrono::duration<double>(Clock::now() - t0).count();
    t0 = Clock::now();
    for (int f = 0; f < frames; ++f) gen.render_frame(f, frame, threads);
    const double full_s = std::chrono::duration<double>(Clock::now() - t0).count();
    int nt = 1;
#ifdef _OPENMP
    nt = threads > 0 ? threads : omp_get_max_threads();
#endif
    std::printf("bench: %dx%d, %zu objects, %lld triangles, %d threads, %d frames\n",
                cfg.camera.width, cfg.camera.height, models.size(), (long long)tris, nt, frames);
    std::printf("  rasterizer only : %7.1f frames/s (%.2f ms/frame)\n", frames / raster_s,
                1e3 * raster_s / frames);
    std::printf("  full scene frame: %7.1f frames/s (%.2f ms/frame: sampling, render, per-"
                "instance solo renders, noise)\n",
                frames / full_s, 1e3 * full_s / frames);
    return 0;
}

// The ids and names of meshes not named as BOP names them, said and kept in obj_names.json.
void write_names(const std::vector<LoadedModel>& models, const fs::path& root) {
    std::map<int, std::string> names;
    bool renamed = false;
    for (const LoadedModel& m : models) {
        names[m.obj_id] = m.name;
        renamed |= data::bop_mesh_id(m.name) != m.obj_id;
    }
    if (!renamed) return;
    for (const auto& [id, name] : names)
        std::fprintf(stderr, "g2l_render: object %d = %s\n", id, name.c_str());
    data::write_obj_names(root.string(), names);
}

// Frames writer.next_image_id() .. frames - 1, with progress; after the first, the disk must
// hold the rest (at that frame's size, + 25 %), else the scene stops there, listed and marked
// incomplete, and the error says how to go on.
void render_frames(data::SceneGenerator& gen, data::BopSceneWriter& writer, int64_t frames,
                   int threads) {
    const bool tty = isatty(fileno(stderr));
    const auto t0 = Clock::now();
    auto last = t0;
    data::RenderedFrame frame;
    const int64_t first = writer.next_image_id();
    for (int64_t f = first; f < frames; ++f) {
        gen.render_frame(f, frame, threads);
        writer.write(int(f), frame);
        if (f == first && f + 1 < frames) {
            const double per_frame = double(writer.image_bytes(int(f)));
            const double need = 1.25 * per_frame * double(frames - f - 1) + 64e6;
            std::error_code ec;
            const auto space = fs::space(writer.dir(), ec);
            if (!ec && double(space.available) < need) {
                writer.flush();
                G2L_CHECK(false, "--frames ", frames, " needs about ", need / 1e9, " GB more (",
                          per_frame / 1e6, " MB per frame) but the disk of '", writer.dir(),
                          "' has ", double(space.available) / 1e9, " GB free: free some space and "
                          "continue with --resume, or render fewer frames");
            }
        }
        const auto now = Clock::now();
        const bool step = tty ? std::chrono::duration<double>(now - last).count() > 0.2
                              : std::chrono::duration<double>(now - last).count() > 10.0;
        if (step || f + 1 == frames) {
            progress(f + 1 - first, frames - first, std::chrono::duration<double>(now - t0).count(),
                     tty);
            last = now;
        }
        if ((f + 1) % 200 == 0) writer.flush();  // partial output stays readable
    }
    writer.finish();
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"g2l_render: synthetic RGB-D training data (BOP format) from object meshes"};
    std::vector<std::string> model_args;
    std::string objects, out_dir, config_path, split = "train_synt";
    int64_t frames = 100;
    uint64_t seed = 0;
    int threads = 0, scene_id = 0;
    bool bench = false;
    app.add_option("--models", model_args, "mesh folder (obj_NNNNNN.ply) or mesh files")
        ->expected(1, -1);
    app.add_option("--objects", objects, "target object ids, e.g. 1,2,3 (default: all models)")
        ->check(g2l::cli::id_list());
    app.add_option("--out", out_dir, "output dataset root (models/ and <split>/<scene>/)");
    app.add_option("--frames", frames, "number of frames")->check(CLI::Range(int64_t(1), int64_t(1) << 40));
    app.add_option("--seed", seed, "random seed (overrides the config's seed)");
    app.add_option("--config", config_path, "scene config JSON (see docs/renderer.md)");
    app.add_option("--threads", threads, "OpenMP threads (0 = default)")->check(CLI::Range(0, 1024));
    app.add_option("--split", split, "split folder name");
    app.add_option("--scene-id", scene_id, "scene folder number")->check(CLI::Range(0, 999999));
    app.add_flag("--bench", bench, "time the renderer on a ~20k-triangle scene and exit");
    bool force = false;
    app.add_flag("--force", force, "replace an existing <out>/<split>/<scene> folder (without it "
                                   "an existing non-empty scene folder is refused)");
    bool resume = false;
    app.add_flag("--resume", resume, "continue the interrupted render of <out>/<split>/<scene> "
                                     "(it holds render_incomplete.json) with its own "
                                     "scene_config.json and frame count: the scene an "
                                     "uninterrupted render would have written");
    bool verbose = false;
    app.add_flag("--verbose", verbose, "error messages with their source location (also G2L_VERBOSE=1)");
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_render"); rc >= 0) return rc;
    if (resume && (force || app.count("--config") || app.count("--seed") || app.count("--objects") ||
                   app.count("--frames"))) {
        std::fprintf(stderr, "g2l_render: --resume continues a scene with its own config, seed, "
                             "objects and frame count: it takes no --force, --config, --seed, "
                             "--objects or --frames (see g2l_render --help)\n");
        return g2l::cli::kUsageError;
    }
    if (!bench && (model_args.empty() || out_dir.empty())) {
        std::fprintf(stderr, "g2l_render: give --models and --out (unless --bench) (see g2l_render --help)\n");
        return g2l::cli::kUsageError;
    }
    // The split is one folder name inside --out: no path separators, no "." / "..".
    if (split.empty() || split == "." || split == ".." ||
        split.find_first_of("/\\") != std::string::npos) {
        std::fprintf(stderr, "g2l_render: --split must be a plain folder name, got '%s' (see "
                             "g2l_render --help)\n", split.c_str());
        return g2l::cli::kUsageError;
    }
    try {
        const bool seed_given = app.count("--seed") > 0;
        std::vector<LoadedModel> models = load_models(model_args);
        if (bench) return run_bench(std::move(models), int(std::min<int64_t>(frames, 1000)),
                                    threads, seed);
        char scene_name[16];
        std::snprintf(scene_name, sizeof scene_name, "%06d", scene_id);
        const fs::path root(out_dir);
        const fs::path scene_dir = root / split / scene_name;
        if (resume) config_path = (scene_dir / "scene_config.json").string();
        data::SceneConfig cfg =
            config_path.empty() ? data::SceneConfig{} : data::load_scene_config(config_path);
        if (seed_given) cfg.seed = seed;
        if (app.count("--objects") > 0) cfg.target_obj_ids = parse_ids(objects);
        std::vector<data::SceneModel> sm;
        for (const LoadedModel& m : models) sm.push_back({m.obj_id, m.mesh.get(), m.symmetries});
        for (const int id : cfg.target_obj_ids) {  // name the option, not the scene generator
            bool known = false;
            std::string ids;
            for (const auto& m : sm) {
                known |= m.obj_id == id;
                ids += (ids.empty() ? "" : ", ") + std::to_string(m.obj_id);
            }
            G2L_CHECK(known, app.count("--objects") ? "--objects" : "the scene config's target_obj_ids",
                      ": object ", id, " is not among the meshes of --models (", ids, ")");
        }
        data::SceneGenerator gen(cfg, sm);

        data::write_bop_models((root / "models").string(), sm);
        write_names(models, root);
        if (resume) {
            data::BopSceneWriter writer = data::BopSceneWriter::resume(scene_dir.string());
            std::fprintf(stderr, "g2l_render: resuming '%s' at frame %d of %lld\n",
                         scene_dir.string().c_str(), writer.next_image_id(),
                         (long long)writer.planned());
            render_frames(gen, writer, writer.planned(), threads);
            std::printf("wrote %lld frames to %s\n", (long long)writer.planned(),
                        writer.dir().c_str());
            return 0;
        }
        if (fs::exists(scene_dir) && !fs::is_empty(scene_dir)) {
            G2L_CHECK(force, "'", scene_dir.string(), "' already holds a rendered scene: its images "
                      "would mix with the new ones; choose another --out / --split / --scene-id, "
                      "or replace it with --force (an interrupted one continues with --resume)");
            fs::remove_all(scene_dir);
        }
        data::BopSceneWriter writer(scene_dir.string(), frames);
        write_file_atomic((scene_dir / "scene_config.json").string(),
                          data::scene_config_to_json(cfg) + "\n");
        render_frames(gen, writer, frames, threads);
        std::printf("wrote %lld frames to %s\n", (long long)frames, writer.dir().c_str());
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_render", e, verbose);
    }
}
