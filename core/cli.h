// SPDX-License-Identifier: MIT
// What every g2l command-line tool shares (header-only; included by the *_main.cpp files only):
// one exit-code convention, one way to report a bad command line, number checks with short
// messages, and error messages without the developer suffix unless --verbose / G2L_VERBOSE.
//
// Exit codes: 0 success (and --help), 1 the command failed (a file, a config, the data),
// 2 a bad command line (unknown option, missing or out-of-range value).
#pragma once

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

namespace g2l::cli {

constexpr int kRunError = 1;
constexpr int kUsageError = 2;

namespace detail {
inline const char*& tool_name() {
    static const char* name = "g2l";
    return name;
}
inline bool& stdout_reported() {
    static bool reported = false;
    return reported;
}
// At exit: what the tool printed must have reached its standard output (a full disk, /dev/full,
// a closed pipe); otherwise one line on stderr and exit code kRunError, never a silent 0.
inline void check_stdout_at_exit() {
    if (stdout_reported()) return;  // the tool said it already (and exits 1)
    errno = 0;
    if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
        const int err = errno;
        std::fprintf(stderr, "%s: error: cannot write the standard output: %s\n", tool_name(),
                     err ? std::strerror(err) : "write error");
        std::_Exit(kRunError);
    }
}
}  // namespace detail

/// Parses the command line. Returns -1 when the tool should go on, otherwise the exit code: 0
/// after printing --help, kUsageError after one line naming the problem on stderr. Also makes
/// the process check at exit that its standard output was written (exit 1 naming the reason).
inline int parse(CLI::App& app, int argc, char** argv, const char* tool) {
    detail::tool_name() = tool;
    static const bool registered = std::atexit(detail::check_stdout_at_exit) == 0;
    (void)registered;
    try {
        app.parse(argc, argv);
        return -1;
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::fprintf(stderr, "%s: %s (see %s --help)\n", tool, e.what(), tool);
        return kUsageError;
    }
}

/// For a tool that reports its own standard-output failure (naming what it wrote): the check
/// at exit stays quiet.
inline void stdout_failure_reported() { detail::stdout_reported() = true; }

/// A CLI11 check: an integer or number >= lo (the message names the value, not a 300-digit
/// bound).
inline CLI::Validator at_least(double lo) {
    return CLI::Validator(
        [lo](std::string& s) -> std::string {
            char* end = nullptr;
            const double v = std::strtod(s.c_str(), &end);
            if (end == s.c_str() || *end != '\0') return "'" + s + "' is not a number";
            if (!(v >= lo)) {
                char b[64];
                std::snprintf(b, sizeof b, "%g", lo);
                return "must be >= " + std::string(b) + ", got " + s;
            }
            return std::string();
        },
        ">= " + std::to_string(lo));
}

/// True when G2L_VERBOSE is set to something other than "" or "0".
inline bool verbose_env() {
    const char* v = std::getenv("G2L_VERBOSE");
    return v && *v && std::string(v) != "0";
}

/// The message of an error for a user: g2l::Error messages end with a developer suffix
/// " [<condition> failed at <file>:<line> in <function>]", kept only when `verbose`.
inline std::string message(const std::exception& e, bool verbose) {
    std::string m = e.what();
    if (verbose) return m;
    const size_t at = m.rfind(" failed at ");
    const size_t open = at == std::string::npos ? std::string::npos : m.rfind(" [", at);
    if (open != std::string::npos && !m.empty() && m.back() == ']') m.erase(open);
    return m;
}

/// Prints "<tool>: error: <message>" on stderr and returns kRunError.
inline int report(const char* tool, const std::exception& e, bool verbose = false) {
    std::fprintf(stderr, "%s: error: %s\n", tool, message(e, verbose || verbose_env()).c_str());
    return kRunError;
}

}  // namespace g2l::cli
