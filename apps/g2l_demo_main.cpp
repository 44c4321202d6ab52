// SPDX-License-Identifier: MIT
// g2l_demo: the main job end to end on data embedded in the repository.
#include <CLI/CLI.hpp>

#include "core/cli.h"
#include <cstdio>

#include "core/threads.h"
#include "tools/toy_pointnet.h"

int main(int argc, char** argv) {
    CLI::App app{"g2l_demo: trains on data embedded in the repository and reports the result"};
    int steps = 300, threads = 0;
    uint64_t seed = 1;
    app.add_option("--steps", steps, "training steps")->check(CLI::Range(1, 1000000));
    app.add_option("--seed", seed, "random seed");
    app.add_option("--threads", threads, "CPU threads (0 = all cores)")->check(CLI::Range(0, 1024));
    bool verbose = false;
    app.add_flag("--verbose", verbose, "error messages with their source location (also G2L_VERBOSE=1)");
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_demo"); rc >= 0) return rc;
    try {
        if (threads > 0) g2l::set_num_threads(threads);
        g2l::tools::ToyConfig cfg;
        cfg.steps = steps;
        cfg.seed = seed;
        std::printf("g2l_demo: PointNet classifier on generated point clouds (sphere / box / "
                    "cylinder, %d points)\n", cfg.points);
        const auto r = g2l::tools::train_toy_pointnet(cfg, [&](int step, double loss) {
            std::printf("  step %4d/%d  loss %.4f\n", step + 1, cfg.steps, loss);
            std::fflush(stdout);
        });
        std::printf("done in %.1f s (%.0f samples/s): loss %.3f -> %.3f, test accuracy %.1f%%\n",
                    r.seconds, r.samples_per_s, r.first_loss, r.final_loss,
                    100 * r.test_accuracy);
        return r.test_accuracy > 0.9 ? 0 : 1;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_demo", e, verbose);
    }
}
