// SPDX-License-Identifier: MIT
// The one training loop. Both trainers — the pose networks (train/trainer.cpp) and the 2D
// detector (train/detector_train.cpp) — are small tasks on it: a task owns its model, its
// optimiser, its data and its checkpoint metadata; the loop owns what every training run needs
// and must do the same way:
//  - the walk over epochs and steps from where a resumed run stopped,
//  - the learning rate of each step (the task's schedule),
//  - the step's ONE data-parallel all-reduce (gradients + the logged values + the stop flags,
//    train/distributed.h), then Adam,
//  - stopping: --max-steps, the config's time limit (across resumes), a signal (SIGINT/SIGTERM
//    seen by any process stops all after the same step),
//  - the JSONL logs (steps.jsonl: the values averaged since the last record; epochs.jsonl),
//  - progress on stdout with throughput and ETA (a bar on a terminal, lines otherwise),
//  - the save cadence: last.g2l every N steps, at each epoch's end and on a stop; best.g2l when
//    validation improves; epoch_<k>.g2l every k epochs; the "stopped" record that says which
//    step last.g2l holds and why the run stopped.
// A new trainer (a verifier, a refiner, another detector) is a new TrainTask, not a third loop.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "nn/optim.h"
#include "train/run_dir.h"
#include "train/trainer.h"

namespace g2l::train {

/// Where a run stands. A checkpoint stores it (in the task's metadata) and a resumed run starts
/// from it.
struct LoopState {
    int epoch = 0;            ///< the epoch being trained (0-based)
    int64_t epoch_step = 0;   ///< steps done in this epoch
    int64_t step = 0;         ///< steps done in the whole run (the global optimiser steps)
    double epoch_loss = 0;    ///< sum of this epoch's step losses (its mean is epoch_loss / epoch_step)
    double best_val = -1;     ///< best validation score so far (-1: none yet)
    double seconds = 0;       ///< training time of the whole run, earlier sessions included
};

/// One named value of a step (a loss term, an accuracy), as this process contributes it to
/// the global batch's value: the loop sums the processes' contributions in the all-reduce, so a
/// task weights by its share of the batch where the value is a mean over the batch. The first
/// value of a step is its total loss.
using StepValues = std::vector<std::pair<std::string, double>>;

/// Thrown by a task's step when TrainOptions::stop_flag rises while it gathers its batch (a big
/// batch can take minutes): nothing of the step has been applied, so the loop saves the state
/// before it and stops as for a signal. One process only — with several, the flag travels in
/// the step's all-reduce so that every process stops after the same step.
struct StepInterrupted : std::runtime_error {
    StepInterrupted() : std::runtime_error("interrupted while gathering the batch") {}
};

/// The share of the run done at `s` by the clock (s.seconds / time limit) when that is ahead
/// of `by_steps`, else by_steps: what a time-fitted schedule follows (time_schedule).
double time_fitted_progress(const LoopState& s, double by_steps, double time_limit_min);

/// True when a task may throw StepInterrupted now (the flag is up, one process).
bool interrupt_now(const TrainOptions& opt);

/// What the loop needs from a trainer.
class TrainTask {
public:
    virtual ~TrainTask() = default;
    /// The optimiser the loop steps (after the all-reduce) and whose learning rate it sets.
    virtual nn::Adam& optimizer() = 0;
    /// The learning rate of the step about to run at `s` (s.seconds is current).
    virtual double lr(const LoopState& s) const = 0;
    /// Prepares epoch `s.epoch` (its data order, the model's training mode); returns the
    /// number of steps it has (> 0).
    virtual int64_t begin_epoch(const LoopState& s) = 0;
    /// One step on this process's share of the global batch: gradients zeroed, forward,
    /// backward. Returns the step's values (see StepValues); throws g2l::Error on a
    /// non-finite loss, naming what it can.
    virtual StepValues step(const LoopState& s) = 0;
    /// After each step (its log record written and its checkpoint saved): e.g. a validation
    /// every N steps.
    virtual void after_step(const LoopState& /*s*/) {}
    /// At the end of an epoch that ran to its end and was not interrupted (`s.epoch` is still
    /// the finished one): validation. Returns the score (higher is better; best.g2l keeps the
    /// best) or < 0 when it did not validate; may add to the epoch's record.
    virtual double end_epoch(const LoopState& /*s*/, nlohmann::json& /*record*/) { return -1; }
    /// Writes a training checkpoint of the state `s` to `path` (atomically; rank 0 only).
    virtual void save(const std::string& path, const LoopState& s) = 0;
};

struct LoopOptions {
    int epochs = 1;                     ///< the run's length in epochs (a step-counted run: 1)
    int64_t global_batch = 1;           ///< samples per step over all processes (throughput, ETA)
    int log_every = 25;                 ///< a steps.jsonl record (and a progress line) every N steps
    int64_t checkpoint_every_steps = 0; ///< last.g2l every N steps (0: epoch ends and stops only)
    int keep_every_epochs = 0;          ///< epoch_<k>.g2l every k epochs (0: none)
    double time_limit_min = 0;          ///< 0 = none; stop with a checkpoint after this much time
    std::string epoch_log;              ///< the epochs' JSONL log ("" = none)
    int shown_values = 4;               ///< how many of the step values the progress shows
    const char* unit = "samples";       ///< what the throughput counts
};

struct LoopResult {
    LoopState state;             ///< where the run stands at the end
    bool finished = false;       ///< every epoch done
    bool stopped_early = false;  ///< stopped before the end (max_steps, time limit or signal)
    bool interrupted = false;    ///< a signal (TrainOptions::stop_flag)
    std::string stop_reason;     ///< "signal", "max_steps", "time_limit" or ""
    double last_loss = 0;        ///< mean loss of the last (or the partial) epoch
    double last_step_loss = 0;   ///< the last step's loss
    double samples_per_s = 0;    ///< throughput of this session (global batch)
};

/// Runs `task` from `start` (a fresh run: LoopState{}; a resumed one: its checkpoint's state),
/// writing to `run` (begun by the caller), as `lo` and `opt` say. Throws what the task throws
/// and g2l::Error on a failed log or checkpoint write.
LoopResult run_loop(TrainTask& task, const RunDir& run, const LoopOptions& lo,
                    const TrainOptions& opt, LoopState start);

/// "h:mm:ss".
std::string format_duration(double seconds);

}  // namespace g2l::train
