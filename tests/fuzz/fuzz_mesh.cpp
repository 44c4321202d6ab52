// SPDX-License-Identifier: MIT
// libFuzzer target: the mesh readers (PLY ascii / binary little- and big-endian, OBJ). The
// first byte picks the file extension, the rest is the file.
#include <cstdint>
#include <exception>
#include <string>

#include "fuzz_util.h"
#include "geometry/mesh_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    const std::string path = g2l::fuzz::temp_dir() + (data[0] % 2 ? "/m.obj" : "/m.ply");
    g2l::fuzz::write_file(path, data + 1, size - 1);
    try {
        const g2l::geom::Mesh m = g2l::geom::load_mesh(path);
        (void)m.vertices.rows();
    } catch (const std::exception&) {
    }
    return 0;
}
