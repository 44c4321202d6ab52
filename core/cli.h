// SPDX-License-Identifier: MIT
// What every g2l command-line tool shares (header-only; included by the *_main.cpp files only):
// one exit-code convention, one way to report a bad command line, number checks with short
// messages, and error messages without the developer suffix unless --verbose / G2L_VERBOSE.
//
// Exit codes: 0 success (and --help), 1 the command failed (a file, a config, the data),
// 2 a bad command line (unknown option, missing or out-of-range value).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace g2l::cli {

constexpr int kRunError = 1;
constexpr int kUsageError = 2;

/// Parses the command line. Returns -1 when the tool should go on, otherwise the exit code: 0
/// after printing --help, kUsageError after one line naming the problem on stderr.
inline int parse(CLI::App& app, int argc, char** argv, const char* tool) {
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
