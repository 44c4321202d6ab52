// SPDX-License-Identifier: MIT
#include "core/error.h"

#include <cstring>

namespace g2l {

void fail(const char* file, int line, const char* func, const char* cond, const std::string& msg) {
    // Keep only the path below the repository root so messages stay short and stable.
    const char* short_file = file;
    for (const char* key : {"/core/", "/kernels/", "/nn/", "/train/", "/infer/", "/geometry/",
                            "/data/", "/tests/"}) {
        if (const char* p = std::strstr(file, key)) { short_file = p + 1; break; }
    }
    // The caller's message comes first (what went wrong, with values); the failed condition and
    // location follow in brackets for whoever debugs it.
    throw Error(cat(msg, " [", cond, " failed at ", short_file, ":", line, " in ", func, "]"));
}

}  // namespace g2l
