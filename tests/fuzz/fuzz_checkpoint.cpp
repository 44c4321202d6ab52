// SPDX-License-Identifier: MIT
// libFuzzer target: checkpoint files (core/checkpoint.h) and model loading on top of them
// (nn/models/g2l_io.h: metadata JSON, network config, tensor shapes).
#include <cstdint>
#include <exception>
#include <string>

#include "core/checkpoint.h"
#include "fuzz_util.h"
#include "nn/models/detector.h"
#include "nn/models/g2l_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = g2l::fuzz::temp_dir() + "/c.g2l";
    g2l::fuzz::write_file(path, data, size);
    try {
        const g2l::Checkpoint ck = g2l::load_checkpoint(path);
        (void)ck.tensors.size();
        const g2l::nn::LoadedModel m = g2l::nn::load_model(path);
        (void)m.class_of.size();
    } catch (const std::exception&) {
    }
    try {  // the same bytes as a detector export
        const g2l::nn::LoadedDetector d = g2l::nn::load_detector(path);
        (void)d.object_ids.size();
    } catch (const std::exception&) {
    }
    return 0;
}
