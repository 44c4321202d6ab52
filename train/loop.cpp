// SPDX-License-Identifier: MIT
#include "train/loop.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "train/distributed.h"

namespace g2l::train {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
}

// The values of the steps since the last log record, summed (their mean goes in the record).
struct Window {
    StepValues sum;
    double step_s = 0, allreduce_s = 0;
    int n = 0;
    void add(const StepValues& v, double dt, double ar) {
        if (sum.empty()) sum.assign(v.size(), {"", 0.0});
        for (size_t i = 0; i < v.size(); ++i) sum[i] = {v[i].first, sum[i].second + v[i].second};
        step_s += dt;
        allreduce_s += ar;
        ++n;
    }
    double mean(size_t i) const { return sum[i].second / std::max(1, n); }
};

// "loss 0.1234 seg 0.0567 ..." of the first `shown` values.
std::string values_text(const StepValues& v, int shown) {
    std::string s;
    char b[64];
    for (size_t i = 0; i < v.size() && int(i) < shown; ++i) {
        std::snprintf(b, sizeof b, "%s%s %.4g", i ? " " : "", v[i].first.c_str(), v[i].second);
        s += b;
    }
    return s;
}


// The step's ONE all-reduce: every gradient, the step's values and the stop flags (a signal or
// the time limit seen by any process stops all after this step). Returns its seconds.
double reduce_step(const nn::Adam& adam, StepValues& v, bool& signal, bool& time_limit) {
    std::vector<float> extra;
    for (const auto& kv : v) extra.push_back(float(kv.second));
    extra.push_back(signal ? 1.f : 0.f);
    extra.push_back(time_limit ? 1.f : 0.f);
    const double seconds = dist::allreduce_gradients(adam, extra);
    if (dist::size() > 1)  // the global batch's values (one process: kept in double)
        for (size_t i = 0; i < v.size(); ++i) v[i].second = extra[i];
    signal = extra[v.size()] > 0;
    time_limit = extra[v.size() + 1] > 0;
    return seconds;
}

// Where a step leaves the run, for its log record and progress line.
struct Report {
    const LoopState& s;
    int64_t epoch_steps;  // steps of this epoch
    double rate;          // samples (images) per second in this session
    double run_s;         // training seconds of the whole run
};

// The steps.jsonl record: the values averaged over the steps since the last record.
void write_record(const RunDir& run, const LoopOptions& lo, const Report& at, const Window& win,
                  double lr) {
    json j = {{"step", at.s.step}, {"epoch", at.s.epoch}, {"lr", lr}};
    for (size_t i = 0; i < win.sum.size(); ++i) j[win.sum[i].first] = win.mean(i);
    j["step_s"] = win.step_s / win.n;
    j[cat(lo.unit, "_per_s")] = at.rate;
    j["minutes"] = at.run_s / 60;
    if (dist::size() > 1) j["allreduce_s"] = win.allreduce_s / win.n;
    run.append("steps.jsonl", j);
}

// "epoch 2/4 step 37/100  loss 1.23 seg 0.1 ... | 5.1 samples/s ETA 0:12:03", or with a bar.
// The ETA counts the steps left at this session's rate, capped by the time limit.
std::string progress_text(const LoopOptions& lo, const Report& at, const StepValues& v, bool bar) {
    const LoopState& s = at.s;
    const double left = double(at.epoch_steps - s.epoch_step) +
                        double(lo.epochs - s.epoch - 1) * double(at.epoch_steps);
    double eta = left * double(lo.global_batch) / std::max(1e-9, at.rate);
    if (lo.time_limit_min > 0) eta = std::min(eta, std::max(0.0, lo.time_limit_min * 60 - at.run_s));
    std::string out = lo.epochs > 1 ? cat("epoch ", s.epoch + 1, "/", lo.epochs, " ") : "";
    if (bar) {
        const int width = 24, fill = int(width * s.epoch_step / at.epoch_steps);
        out += "[" + std::string(size_t(fill), '#') + std::string(size_t(width - fill), '.') + "] ";
    } else {
        out += "step ";
    }
    char b[96];
    std::snprintf(b, sizeof b, "%lld/%lld  ", (long long)s.epoch_step, (long long)at.epoch_steps);
    out += b + values_text(v, lo.shown_values);
    std::snprintf(b, sizeof b, " | %.2f %s/s ETA ", at.rate, lo.unit);
    return out + b + format_duration(eta);
}

// The end of an epoch that ran to its end: the task's validation (not after a signal), the
// epoch's record and line. Returns the validation score (< 0: none).
double end_of_epoch(TrainTask& task, const RunDir& run, const LoopOptions& lo, const LoopState& s,
                    bool interrupted, double lr, double seconds, bool progress) {
    json ej = {{"epoch", s.epoch}, {"loss", s.epoch_loss / double(s.epoch_step)},
               {"batches", s.epoch_step}, {"lr", lr}, {"seconds", seconds}};
    const double val = interrupted ? -1 : task.end_epoch(s, ej);
    if (!lo.epoch_log.empty()) run.append(lo.epoch_log, ej);
    if (progress && lo.epochs > 1) {
        std::printf("epoch %d/%d done: loss %.4f", s.epoch + 1, lo.epochs,
                    s.epoch_loss / double(s.epoch_step));
        if (val >= 0) std::printf(" validation %.2f", val);
        std::printf("\n");
        std::fflush(stdout);
    }
    return val;
}

}  // namespace

double time_fitted_progress(const LoopState& s, double by_steps, double time_limit_min) {
    if (time_limit_min <= 0) return by_steps;
    return std::max(by_steps, std::min(1.0, s.seconds / (time_limit_min * 60)));
}

bool interrupt_now(const TrainOptions& opt) {
    return opt.stop_flag && opt.stop_flag->load() && dist::size() == 1;
}

std::string format_duration(double seconds) {
    char b[32];
    const int t = int(std::max(0.0, seconds) + 0.5);
    std::snprintf(b, sizeof b, "%d:%02d:%02d", t / 3600, (t / 60) % 60, t % 60);
    return b;
}

LoopResult run_loop(TrainTask& task, const RunDir& run, const LoopOptions& lo,
                    const TrainOptions& opt, LoopState s) {
    const bool progress = opt.progress && dist::is_root();
    const bool tty = progress && isatty(fileno(stdout));
    nn::Adam& adam = task.optimizer();
    const auto t_start = Clock::now();
    const double seconds_before = s.seconds;  // earlier sessions of this run
    const int64_t start_step = s.step;
    const double limit_s = lo.time_limit_min * 60;
    auto save = [&](const std::string& name) {
        if (!dist::is_root()) return;  // the checkpoint holds the global state: one writer
        s.seconds = seconds_before + since(t_start);
        task.save(run.path(name), s);
    };
    auto rate = [&] { return double(s.step - start_step) * double(lo.global_batch) /
                             std::max(1e-9, since(t_start)); };
    LoopResult r;
    Window win;
    bool stop = false;
    while (s.epoch < lo.epochs && !stop) {
        const int64_t n = task.begin_epoch(s);
        G2L_CHECK(n > 0, "training: epoch ", s.epoch, " has no step to run");
        const auto t_epoch = Clock::now();
        while (s.epoch_step < n) {
            s.seconds = seconds_before + since(t_start);  // a schedule may follow the clock
            adam.set_lr(task.lr(s));
            const auto t0 = Clock::now();
            StepValues v;
            try {
                v = task.step(s);
            } catch (const StepInterrupted&) {
                r.interrupted = stop = true;
                r.stop_reason = "signal";
                save("last.g2l");  // the state before this step: nothing of it was applied
                break;
            }
            G2L_CHECK(!v.empty(), "training: a step returned no loss");
            bool any_signal = opt.stop_flag && opt.stop_flag->load();
            bool any_time_limit = limit_s > 0 && seconds_before + since(t_start) >= limit_s;
            const double allreduce_s = reduce_step(adam, v, any_signal, any_time_limit);
            adam.step();
            const double dt = since(t0);
            ++s.step;
            ++s.epoch_step;
            s.epoch_loss += v[0].second;
            r.last_step_loss = v[0].second;
            r.last_loss = s.epoch_loss / double(s.epoch_step);
            win.add(v, dt, allreduce_s);

            const bool last_step = s.epoch_step == n && s.epoch + 1 == lo.epochs;
            const Report at{s, n, rate(), seconds_before + since(t_start)};
            if (s.step % std::max(1, lo.log_every) == 0 || s.epoch_step == 1 || last_step) {
                write_record(run, lo, at, win, adam.lr());
                if (progress && !tty) std::printf("%s\n", progress_text(lo, at, v, false).c_str());
                win = Window();
            }
            if (tty) std::printf("\r%s   ", progress_text(lo, at, v, true).c_str());
            std::fflush(stdout);

            r.interrupted = any_signal;
            r.stop_reason = any_signal ? "signal" : any_time_limit ? "time_limit"
                            : opt.max_steps > 0 && s.step >= opt.max_steps ? "max_steps" : "";
            stop = !r.stop_reason.empty();
            if (s.epoch_step < n && (stop || (lo.checkpoint_every_steps > 0 &&
                                              s.step % lo.checkpoint_every_steps == 0)))
                save("last.g2l");
            if (stop) break;
            task.after_step(s);
        }
        if (tty) std::printf("\n");
        if (s.epoch_step < n) break;  // stopped inside the epoch (last.g2l saved)

        // ---- end of the epoch: validation, the epoch's record, checkpoints ----
        const double val = end_of_epoch(task, run, lo, s, r.interrupted, adam.lr(),
                                        since(t_epoch), progress);
        ++s.epoch;
        s.epoch_step = 0;
        s.epoch_loss = 0;
        if (val > s.best_val) {
            s.best_val = val;
            save("best.g2l");
        }
        if (lo.keep_every_epochs > 0 && s.epoch % lo.keep_every_epochs == 0)
            save(cat("epoch_", s.epoch, ".g2l"));
        save("last.g2l");
    }
    r.finished = s.epoch >= lo.epochs;
    r.stopped_early = stop && !r.finished;
    // A stopped run's log ends at the step its last.g2l holds, with why it stopped: what
    // --resume continues from is in the log.
    if (r.stopped_early)
        run.append("steps.jsonl", {{"step", s.step}, {"epoch", s.epoch}, {"event", "stopped"},
                                   {"reason", r.stop_reason}, {"checkpoint", "last.g2l"}});
    r.samples_per_s = rate();
    s.seconds = seconds_before + since(t_start);
    r.state = s;
    return r;
}

}  // namespace g2l::train
