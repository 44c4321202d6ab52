// SPDX-License-Identifier: MIT
// g2l_bench's measurements: the engine on G2L-Net's layer shapes (spec §4). Each figure is the
// median of several timed repetitions after a warm-up.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace g2l::tools {

struct BenchFigure {
    std::string name;    ///< JSON key, e.g. "shared_mlp_fwd_gflops"
    double value = 0;    ///< in `unit`
    std::string unit;    ///< "GFLOP/s", "ms", "samples/s"
    std::string detail;  ///< shape / what was timed
};

/// Median wall time in seconds of `reps` calls of fn after `warmup` calls.
double median_seconds(const std::function<void()>& fn, int reps, int warmup = 1);

/// Engine figures: shared_mlp_fwd_gflops, shared_mlp_fwdbwd_gflops ([1, 2280, 1000] -> 1024),
/// gemm_peak_gflops (2048^3), plus per-layer timings of G2L-Net's largest shared MLPs.
std::vector<BenchFigure> bench_engine(int reps, bool quick);

/// Training throughput of G2L-Net: forward + losses + backward + Adam on random crops
/// (`points` per crop, `seg_points` after segmentation, batch `batch`, width multiplier `width`).
/// Figure "train_samples_per_s" (plus per-step milliseconds).
std::vector<BenchFigure> bench_training(int reps, double width, int batch, int points,
                                        int seg_points);

/// Batch-1 pose estimation (nn::estimate_pose, eval mode, no graph) on a synthetic crop of
/// 20,000 points: the seg net sees `crop_points`, the T-net and rotation blocks `object_points`
/// (the seg net's output bias is set so that every point is "object", so every stage runs at
/// its full size). Figures "<prefix>" (median ms), "<prefix>_p90" and "<prefix>_min" over `reps`
/// runs after 3 warm-up runs; `width` scales the networks (1 = paper).
/// engine = true: through nn::PoseEngine (the inference library's path); false: the autograd
/// graph in eval mode (nn::estimate_pose), for comparison.
std::vector<BenchFigure> bench_pose(const std::string& prefix, int reps, double width,
                                    int crop_points, int object_points, bool engine = true);

/// The 2D detector on a 640 x 480 RGB frame (nn::detect: input downscale, network, peak
/// decoding) with the default architecture (8 classes, width 16, downscale 2; the weights do not
/// change the time). Figures "detector_ms" (median), "detector_ms_p90" over `reps` runs after 3
/// warm-up runs; with `mirror` (nn::detect's mirrored second pass) "detector_mirror_ms(_p90)".
std::vector<BenchFigure> bench_detector(int reps, int width = 16, int downscale = 2,
                                        bool mirror = false);

/// Depth refinement (geom::refine_pose with the near-symmetric turns, point-to-plane, a support
/// plane and the free-space test: what --refine turns runs per object) of a 150 x 90 x 60 mm
/// box with a 30 mm bump (2 mm surface samples) seen at 800 mm on a table in a 640 x 480 depth
/// image (1,000 of its visible points, about the object points of a crop), from a start 20
/// degrees and 15 mm off. Figures "refine_ms" (median, with the
/// ClosestPointGrid as g2l_eval and the library run it), "refine_ms_p90", "refine_tree_ms" (k-d
/// tree only, for comparison) and "refine_prepare_ms" (what the frame pipeline prepares once per model: the
/// k-d tree, its normals and the grid) over `reps` runs.
std::vector<BenchFigure> bench_refine(int reps);

/// Peak resident set size of this process so far (MB; getrusage).
double peak_rss_mb();
/// Resident set size of this process now (MB; /proc/self/statm); -1 where unreadable.
double current_rss_mb();

}  // namespace g2l::tools
