// SPDX-License-Identifier: MIT
// The training-job skeleton both trainers (the pose trainer, train/trainer.cpp, and the detector
// trainer, train/detector_train.cpp) run on: the run directory, its config.json, its JSONL logs,
// the checkpoint's tensors (model + Adam state) and the resume rules. What differs between the
// two — the data, the step, the metadata — stays with each trainer; signals are caught once in
// apps/g2l_train_main.cpp and reach both as TrainOptions::stop_flag.
#pragma once

#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "core/tensor.h"
#include "nn/optim.h"

namespace g2l::train {

class RunDir {
public:
    /// Opens the run directory of a job, first thing (a bad one is found before any data is
    /// read), creating it and checking that it is writable:
    ///  - new run (`resume` false): refuses a directory that holds a run (config.json,
    ///    steps.jsonl or last.g2l) unless `force`;
    ///  - resumed run: needs last.g2l, removes the leftovers of a write a kill interrupted
    ///    (<name>.tmp.<pid>; the file they were to replace is intact);
    ///  - then locks it (<dir>/run.lock, held while this object lives): a second writer — another
    ///    g2l_train on the directory, --resume or --force while one runs — is refused, naming the
    ///    process that holds it.
    /// `logs` are the JSONL logs of the job (e.g. "steps.jsonl"). Throws g2l::Error naming the
    /// directory. `writer` false (the ranks other than 0 of a data-parallel job,
    /// train/distributed.h): the directory is only named — no check, and begin / trim_log /
    /// append do nothing; rank 0 alone writes, and the trainers save checkpoints only there.
    RunDir(std::string dir, bool resume, bool force, std::vector<std::string> logs,
           bool writer = true);

    /// Once the job is set up (the checkpoint loaded on a resume): writes `config_json` to
    /// config.json atomically — on a resume that is the effective config, `--set` overrides
    /// included, so the directory always says how the run trains now — and, for a new run,
    /// empties the logs. Throws naming the file and the OS reason.
    void begin(const std::string& config_json) const;

    const std::string& dir() const { return dir_; }
    bool resumed() const { return resumed_; }
    /// False on the non-writing ranks of a data-parallel job.
    bool writer() const { return writer_; }
    /// <dir>/<name>.
    std::string path(const std::string& name) const;

    /// After a resume: keeps only the records of log `log` whose numeric `key` is <= max_value
    /// (a killed run logs past its last checkpoint; the resumed one logs those steps again).
    void trim_log(const std::string& log, const std::string& key, int64_t max_value) const;
    /// Appends one record to log `log` (one of the constructor's), flushed; a failed write
    /// throws naming the file and the OS reason.
    void append(const std::string& log, const nlohmann::json& record) const;

private:
    std::string dir_;
    bool resumed_ = false;
    bool writer_ = true;
    std::vector<std::string> logs_;
    std::shared_ptr<int> lock_;  // the open run.lock (writer only): one writer per directory
};

/// The tensors of a training checkpoint: the model's state under "model.<name>" and the
/// optimiser's moments (nn::Adam::state_tensors). Both trainers save exactly this, plus their
/// own metadata, with core's atomic save_checkpoint.
std::vector<std::pair<std::string, Tensor>> checkpoint_tensors(
    const std::map<std::string, Tensor>& model_state, const nn::Adam& adam);

/// The model part of a checkpoint's tensors ("model." prefix removed).
std::map<std::string, Tensor> model_state_of(const std::map<std::string, Tensor>& tensors);

}  // namespace g2l::train
