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
        int err = errno;
        if (err == 0) {  // a write failed earlier (a long text) and its errno is gone: ask again
            std::clearerr(stdout);
            errno = 0;
            if (std::fputc('\n', stdout) == EOF || std::fflush(stdout) != 0) err = errno;
        }
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
        std::string msg = e.what();
        // CLI11 checks required options before unknown ones: "--dpeth x" would be reported as
        // "--depth is required", or as "the following arguments were not expected: x --dpeth".
        // Name the misspelt option instead.
        if (dynamic_cast<const CLI::RequiredError*>(&e) || dynamic_cast<const CLI::ExtrasError*>(&e)) {
            for (int i = 1; i < argc; ++i) {
                const std::string a = argv[i];
                if (a.size() < 3 || a.compare(0, 2, "--") != 0) continue;
                const std::string name = a.substr(0, a.find('='));
                if (!app.get_option_no_throw(name)) {
                    msg = "unknown option '" + name + "'";
                    break;
                }
            }
        }
        std::fprintf(stderr, "%s: %s (see %s --help)\n", tool, msg.c_str(), tool);
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

/// A CLI11 check: comma-separated positive integers ("1,5,8"), each below 10^9.
inline CLI::Validator id_list() {
    return CLI::Validator(
        [](std::string& s) -> std::string {
            size_t start = 0;
            do {
                const size_t end = std::min(s.find(',', start), s.size());
                const std::string tok = s.substr(start, end - start);
                if (tok.empty() || tok.size() > 9 ||
                    tok.find_first_not_of("0123456789") != std::string::npos ||
                    std::strtol(tok.c_str(), nullptr, 10) < 1)
                    return "'" + tok + "' is not a positive integer (in '" + s + "')";
                start = end + 1;
            } while (start <= s.size());
            return std::string();
        },
        "ID,ID,...");
}

/// A CLI11 check for --set: "key.path=value" with a non-empty key.
inline CLI::Validator key_value() {
    return CLI::Validator(
        [](std::string& s) -> std::string {
            const size_t eq = s.find('=');
            if (eq == std::string::npos || eq == 0)
                return "'" + s + "': expected key.path=value (e.g. optim.lr=5e-4)";
            return std::string();
        },
        "KEY=VALUE");
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
