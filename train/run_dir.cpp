// SPDX-License-Identifier: MIT
#include "train/run_dir.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include "core/atomic_file.h"
#include "core/error.h"

namespace g2l::train {

namespace fs = std::filesystem;

namespace {

// One writer per run directory: an exclusive flock on <dir>/run.lock, held while the RunDir
// lives (the kernel drops it when the process dies, even by SIGKILL: no stale lock to clean).
// The file says who holds it, so the refusal can name the other process.
std::shared_ptr<int> lock_run_dir(const std::string& dir) {
    const std::string path = (fs::path(dir) / "run.lock").string();
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    G2L_CHECK(fd >= 0, "cannot open the run directory's lock '", path, "': ", std::strerror(errno));
    // Non-blocking: a second writer is refused at once instead of waiting behind the first.
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
        const int err = errno;
        char buf[128] = {0};
        // The holder wrote its pid into the file; read it so the error can name the process.
        const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
        ::close(fd);
        std::string who = n > 0 ? std::string(buf, size_t(n)) : std::string("unknown process");
        while (!who.empty() && (who.back() == '\n' || who.back() == ' ')) who.pop_back();
        G2L_CHECK(err != EWOULDBLOCK, "run directory '", dir, "' is in use by another g2l_train (",
                  who, "): wait for it to finish or stop it (Ctrl-C / kill) before --resume or "
                  "--force");
        G2L_CHECK(false, "cannot lock the run directory '", dir, "' (", path, "): ",
                  std::strerror(err));
    }
    const std::string me = "pid " + std::to_string(::getpid()) + "\n";
    // Truncate first: the file may still hold a previous holder's (longer) text.
    const bool wrote = ::ftruncate(fd, 0) == 0 &&
                       ::pwrite(fd, me.data(), me.size(), 0) == ssize_t(me.size());
    if (!wrote) {
        const int err = errno;
        ::close(fd);
        G2L_CHECK(false, "cannot write the run directory's lock '", path, "': ", std::strerror(err));
    }
    // Closing the descriptor is what releases the lock, so the deleter does exactly that, once,
    // when the last owner goes.
    return std::shared_ptr<int>(new int(fd), [](int* p) {
        ::close(*p);  // releases the lock
        delete p;
    });
}

}  // namespace

RunDir::RunDir(std::string dir, bool resume, bool force, std::vector<std::string> logs,
               bool writer)
    : dir_(std::move(dir)), resumed_(resume), writer_(writer), logs_(std::move(logs)) {
    G2L_CHECK(!dir_.empty(), "run_dir is empty");
    if (!writer_) return;
    std::error_code ec;
    if (!resume) {
        for (const char* f : {"config.json", "steps.jsonl", "last.g2l"})
            G2L_CHECK(force || !fs::exists(fs::path(dir_) / f, ec), "run directory '", dir_,
                      "' already holds a run (", f, "): continue it with --resume ", dir_,
                      ", or start over with --force");
    } else {
        G2L_CHECK(fs::is_regular_file(fs::path(dir_) / "last.g2l"), "--resume '", dir_,
                  "': no last.g2l there (not a run directory, or the run never saved)");
    }
    fs::create_directories(dir_, ec);
    G2L_CHECK(!ec && fs::is_directory(dir_), "cannot create the run directory '", dir_, "': ",
              ec ? ec.message() : std::string("not a directory"));
    lock_ = lock_run_dir(dir_);  // before touching anything another writer may be writing
    if (resume) {
        // AtomicFile temporaries (<name>.tmp.<pid>) of a killed writer. Removing them is safe only
        // now that we hold the lock: no live writer can be in the middle of one.
        for (const auto& e : fs::directory_iterator(dir_, ec)) {
            const std::string name = e.path().filename().string();
            if (name.find(".g2l.tmp.") != std::string::npos ||
                name.find(".json.tmp.") != std::string::npos ||
                name.find(".jsonl.tmp.") != std::string::npos)
                fs::remove(e.path(), ec);
        }
    }
    // Fail now, not at the first checkpoint hours into the run.
    const fs::path probe = fs::path(dir_) / ".write_test";
    {
        std::ofstream t(probe);
        t << "ok";
        t.flush();
        G2L_CHECK(t.good(), "the run directory '", dir_, "' is not writable: ",
                  std::strerror(errno));
    }
    fs::remove(probe, ec);
}

void RunDir::begin(const std::string& config_json) const {
    if (!writer_) return;
    write_file_atomic((fs::path(dir_) / "config.json").string(), config_json);
    if (resumed_) return;
    // A new run (possibly --force over an old one) starts with empty logs.
    for (const std::string& l : logs_) {
        std::ofstream t(path(l), std::ios::trunc);
        G2L_CHECK(t.good(), "cannot write '", path(l), "': ", std::strerror(errno));
    }
}

std::string RunDir::path(const std::string& name) const { return (fs::path(dir_) / name).string(); }

void RunDir::trim_log(const std::string& log, const std::string& key, int64_t max_value) const {
    if (!writer_) return;
    std::ifstream in(path(log));
    if (!in) return;  // a run killed before its first record
    std::vector<std::string> keep;
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty()) continue;
        try {
            const nlohmann::json j = nlohmann::json::parse(line);
            if (j.is_object() && j.contains(key) && j.at(key).is_number() &&
                j.at(key).get<double>() > double(max_value))
                continue;
        } catch (const nlohmann::json::exception&) {
            continue;  // a torn last line from a killed run
        }
        keep.push_back(line);
    }
    in.close();
    std::string text;
    for (const auto& l : keep) text += l + "\n";
    // Atomic: a kill during the rewrite leaves the old log, never a half-written one.
    write_file_atomic(path(log), text);
}

void RunDir::append(const std::string& log, const nlohmann::json& record) const {
    G2L_CHECK(std::find(logs_.begin(), logs_.end(), log) != logs_.end(), "RunDir::append: '", log,
              "' is not a log of this run");
    // The check above runs on every rank, so a misnamed log fails everywhere, not only on rank 0.
    if (!writer_) return;
    std::ofstream f(path(log), std::ios::app);
    f << record.dump() << "\n";
    // Flushed per record: a killed run's log is complete up to its last step.
    f.flush();
    G2L_CHECK(f.good(), "cannot write '", path(log), "': ", std::strerror(errno));
}

std::vector<std::pair<std::string, Tensor>> checkpoint_tensors(
    const std::map<std::string, Tensor>& model_state, const nn::Adam& adam) {
    std::vector<std::pair<std::string, Tensor>> out;
    // The prefix keeps model tensors apart from Adam's "adam.*" state in the one checkpoint.
    for (const auto& [name, t] : model_state) out.emplace_back("model." + name, t);
    for (auto& p : adam.state_tensors()) out.push_back(p);
    return out;
}

std::map<std::string, Tensor> model_state_of(const std::map<std::string, Tensor>& tensors) {
    std::map<std::string, Tensor> sd;
    for (const auto& [name, t] : tensors)
        if (name.rfind("model.", 0) == 0) sd.emplace(name.substr(6), t);
    return sd;
}

}  // namespace g2l::train
