// SPDX-License-Identifier: MIT
// Errors: every failure a caller, file or config can cause throws g2l::Error with file, line,
// function, the failed condition and a message giving the actual values. Library code never
// exits or aborts; only main() catches.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace g2l {

/// The one exception type thrown by g2l for bad input, bad files and broken invariants.
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// Throws g2l::Error("<msg> [<cond> failed at <file>:<line> in <func>]"). Never returns.
[[noreturn]] void fail(const char* file, int line, const char* func, const char* cond,
                       const std::string& msg);

/// Concatenates anything streamable into one string (used to build error messages).
template <class... A>
std::string cat(const A&... a) {
    std::ostringstream s;
    (s << ... << a);
    return s.str();
}

}  // namespace g2l

/// Always-on check for anything the caller, a file or a config can get wrong.
#define G2L_CHECK(cond, ...)                                                         \
    do {                                                                             \
        if (!(cond)) ::g2l::fail(__FILE__, __LINE__, __func__, #cond, ::g2l::cat(__VA_ARGS__)); \
    } while (0)

/// Our own invariants: a failure is a g2l bug.
#define G2L_ASSERT(cond) G2L_CHECK(cond, "internal invariant broken (g2l bug)")

#ifdef NDEBUG
#define G2L_DASSERT(cond) ((void)0)
#else
#define G2L_DASSERT(cond) G2L_ASSERT(cond)
#endif
