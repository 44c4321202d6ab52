// SPDX-License-Identifier: MIT
// g2l_bench: prints the engine's speed on G2L-Net's shapes; --json prints one JSON object.
#include <CLI/CLI.hpp>

#include "core/cli.h"
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/threads.h"
#include "train/bench.h"

int main(int argc, char** argv) {
    CLI::App app{"g2l_bench: times the g2l engine on G2L-Net layer shapes (medians of repeated "
                 "runs). Figures are machine-dependent; see docs/results.md for recorded ones."};
    bool json = false, quick = false;
    int reps = 7, threads = 0, train_reps = 5;
    double width = 1.0;
    app.add_flag("--json", json, "print one JSON object instead of a table");
    app.add_flag("--quick", quick, "fewer and smaller measurements (for smoke tests)");
    app.add_option("--reps", reps, "timed repetitions per figure (median reported)")
        ->check(CLI::Range(1, 1000));
    app.add_option("--threads", threads, "OpenMP threads (0 = OMP_NUM_THREADS / all cores)")
        ->check(CLI::Range(0, 1024));
    app.add_option("--train-reps", train_reps, "timed G2L-Net training steps (0 = skip)")
        ->check(CLI::Range(0, 1000));
    app.add_option("--width", width, "G2L-Net width multiplier for the training figure")
        ->check(CLI::Range(0.01, 4.0));
    bool verbose = false;
    app.add_flag("--verbose", verbose, "error messages with their source location (also G2L_VERBOSE=1)");
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_bench"); rc >= 0) return rc;
    try {
        if (threads > 0) g2l::set_num_threads(threads);
        auto figs = g2l::train::bench_engine(reps, quick);
        if (train_reps > 0) {
            // The setting: paper architecture, batch 8, 1500 -> 1000 points.
            const auto tf = quick ? g2l::train::bench_training(1, width, 2, 300, 200)
                                  : g2l::train::bench_training(train_reps, width, 8, 1500, 1000);
            figs.insert(figs.end(), tf.begin(), tf.end());
        }
        if (json) {
            nlohmann::json j;
            j["threads"] = g2l::num_threads();
            for (const auto& f : figs) j[f.name] = f.value;
            std::cout << j.dump(2) << "\n";
        } else {
            std::printf("g2l_bench (%d threads, median of %d)\n", g2l::num_threads(), reps);
            for (const auto& f : figs)
                std::printf("  %-28s %10.2f %-9s  %s\n", f.name.c_str(), f.value, f.unit.c_str(),
                            f.detail.c_str());
        }
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_bench", e, verbose);
    }
}
