// SPDX-License-Identifier: MIT
// The training-job skeleton both trainers run on (train/run_dir.h).
#include <catch2/catch.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/error.h"
#include "nn/optim.h"
#include "testing.h"
#include "train/run_dir.h"

using Catch::Contains;
using g2l::train::RunDir;
namespace fs = std::filesystem;

namespace {

std::string read(const std::string& path) {
    std::ifstream f(path);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

}  // namespace

TEST_CASE("RunDir: a new run, a refused one, a resumed one", "[train]") {
    const std::string dir = g2l::testing::temp_dir("rundir") + "/run";
    {
        const RunDir run(dir, false, false, {"steps.jsonl", "epochs.jsonl"});
        CHECK(fs::is_directory(dir));
        CHECK_FALSE(run.resumed());
        CHECK(run.path("last.g2l") == dir + "/last.g2l");
        run.begin("{\"lr\": 1}\n");
        CHECK(read(dir + "/config.json") == "{\"lr\": 1}\n");
        CHECK(fs::is_regular_file(dir + "/steps.jsonl"));
        CHECK(read(dir + "/epochs.jsonl").empty());
        run.append("steps.jsonl", {{"step", 1}, {"loss", 0.5}});
        run.append("steps.jsonl", {{"step", 2}, {"loss", 0.25}});
        CHECK(read(dir + "/steps.jsonl") == "{\"loss\":0.5,\"step\":1}\n{\"loss\":0.25,\"step\":2}\n");
        REQUIRE_THROWS_WITH(run.append("other.jsonl", {{"step", 1}}),
                            Contains("'other.jsonl' is not a log of this run"));
    }
    // A second fresh run in the same directory is refused (the first is not lost) ...
    REQUIRE_THROWS_WITH(RunDir(dir, false, false, {"steps.jsonl"}),
                        Contains("already holds a run (config.json)") &&
                            Contains("--resume " + dir) && Contains("--force"));
    // ... and --resume needs a checkpoint.
    REQUIRE_THROWS_WITH(RunDir(dir, true, false, {"steps.jsonl"}),
                        Contains("no last.g2l there"));
    REQUIRE_THROWS_WITH(RunDir(g2l::testing::temp_dir("rundir") + "/none", true, false, {}),
                        Contains("no last.g2l there"));

    // A killed run: its checkpoint is at step 2, its log went on to step 4 and ends torn; a
    // checkpoint write it interrupted left a temporary file.
    write(dir + "/last.g2l", "checkpoint");
    write(dir + "/last.g2l.tmp.12345", "half");
    write(dir + "/steps.jsonl",
          "{\"step\":1}\n{\"step\":2}\n{\"step\":3}\n{\"step\":4}\n{\"step\":");
    {
        const RunDir resumed(dir, true, false, {"steps.jsonl", "epochs.jsonl"});
        CHECK(resumed.resumed());
        // One writer at a time: while it holds the directory, a --force or another --resume there
        // is refused, naming the holder.
        REQUIRE_THROWS_WITH(RunDir(dir, false, true, {"steps.jsonl"}),
                            Contains("is in use by another g2l_train (pid " + std::to_string(::getpid()) + ")"));
        REQUIRE_THROWS_WITH(RunDir(dir, true, false, {"steps.jsonl"}), Contains("is in use"));
        CHECK_FALSE(fs::exists(dir + "/last.g2l.tmp.12345"));
        CHECK(read(dir + "/last.g2l") == "checkpoint");
        resumed.trim_log("steps.jsonl", "step", 2);
        CHECK(read(dir + "/steps.jsonl") == "{\"step\":1}\n{\"step\":2}\n");
        resumed.trim_log("epochs.jsonl", "epoch", 0);  // empty: stays empty
        CHECK(read(dir + "/epochs.jsonl").empty());
        // The effective config (--set included) replaces config.json; the logs are kept.
        resumed.begin("{\"lr\": 2}\n");
        CHECK(read(dir + "/config.json") == "{\"lr\": 2}\n");
        CHECK(read(dir + "/steps.jsonl") == "{\"step\":1}\n{\"step\":2}\n");
    }

    // --force starts over in the same directory (the resumed run released it), with empty logs.
    const RunDir forced(dir, false, true, {"steps.jsonl"});
    forced.begin("{}\n");
    CHECK(read(dir + "/steps.jsonl").empty());
}

TEST_CASE("RunDir: an unusable directory or a full disk is an error naming the file", "[train]") {
    const std::string base = g2l::testing::temp_dir("rundir_bad");
    write(base + "/file", "x");
    REQUIRE_THROWS_WITH(RunDir(base + "/file/run", false, false, {}),
                        Contains("cannot create the run directory '" + base + "/file/run'"));
    REQUIRE_THROWS_WITH(RunDir("", false, false, {}), Contains("run_dir is empty"));
    if (fs::exists("/dev/full")) {
        // A log that cannot be written (here: /dev/full behind a symlink) names the file and
        // the OS's reason.
        const RunDir run(base + "/run", false, false, {"steps.jsonl"});
        run.begin("{}\n");
        fs::remove(base + "/run/steps.jsonl");
        fs::create_symlink("/dev/full", base + "/run/steps.jsonl");
        REQUIRE_THROWS_WITH(run.append("steps.jsonl", {{"step", 1}}),
                            Contains("cannot write '" + base + "/run/steps.jsonl'") &&
                                Contains("No space left on device"));
    }
}

TEST_CASE("checkpoint_tensors and model_state_of: the model under 'model.', the Adam state",
          "[train]") {
    g2l::Tensor w = g2l::Tensor::ones({2, 3});
    w.set_requires_grad(true);
    g2l::nn::ParamGroup g;
    g.name = "all";
    g.params = {{"w", w}};
    g2l::nn::Adam adam({g}, {});
    const auto ts = g2l::train::checkpoint_tensors({{"w", w}, {"bn.mean", g2l::Tensor::zeros({3})}},
                                                   adam);
    std::map<std::string, g2l::Tensor> all(ts.begin(), ts.end());
    CHECK(all.count("model.w"));
    CHECK(all.count("model.bn.mean"));
    CHECK(all.size() == 2 + adam.state_tensors().size());
    const auto sd = g2l::train::model_state_of(all);
    CHECK(sd.size() == 2);
    CHECK(sd.count("w"));
    CHECK(sd.at("bn.mean").shape() == std::vector<int64_t>{3});
}
