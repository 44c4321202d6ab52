// SPDX-License-Identifier: MIT
// The g2l_train loop: data sources -> samples -> batches -> G2L-Net step -> Adam, with a run
// directory (effective config, JSONL logs, atomic checkpoints) and exact resume.
#pragma once

#include <atomic>

#include <cstdint>
#include <string>

#include "train/config.h"

namespace g2l::train {

struct TrainOptions {
    std::string resume_dir;   ///< continue the run in this directory (its last.g2l)
    int64_t max_steps = 0;    ///< stop (with a checkpoint) after this many global steps; 0 = none
    bool progress = true;     ///< progress bar on a terminal / plain lines otherwise; false: silent
    /// Start over in a run directory that already holds a run (config.json, steps.jsonl or
    /// last.g2l). Without it (and without resume_dir) such a directory is refused.
    bool force = false;
    /// When set and it becomes true (e.g. from a SIGINT/SIGTERM handler), the run stops after
    /// the current step with a checkpoint (last.g2l), as with max_steps.
    const std::atomic<bool>* stop_flag = nullptr;
};

struct TrainSummary {
    std::string run_dir;
    int64_t steps = 0;           ///< global optimizer steps done (in total, resume included)
    int epochs_done = 0;         ///< completed epochs
    double last_loss = 0;        ///< mean total loss of the last epoch (or partial epoch)
    double best_val = -1;        ///< best validation ADD-S AUC (-1 = no validation ran)
    double samples_per_s = 0;    ///< training throughput of this invocation
    bool stopped_early = false;  ///< max_steps or time limit reached, or stop_flag raised
    bool interrupted = false;    ///< stop_flag raised
};

/// Trains as configured. Writes <run_dir>/config.json, steps.jsonl, epochs.jsonl, and
/// checkpoints last.g2l, best.g2l, epoch_<k>.g2l. Throws g2l::Error on bad data or a non-finite
/// loss (naming the step and the samples' objects).
TrainSummary run_training(const TrainConfig& cfg, const TrainOptions& opt);

}  // namespace g2l::train
