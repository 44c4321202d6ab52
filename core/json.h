// SPDX-License-Identifier: MIT
// The one strict JSON parser behind every JSON reader of g2l (configs, scene configs, BOP
// files, models_info, detection files, checkpoint metadata, camera files). Strict means: a
// syntax error names the source and the byte where it was found; a key repeated in one object
// is an error naming the key path (nlohmann-json, like most parsers, would silently keep the
// last one: a config with "lr" twice would train with whichever came last); the top level must
// be a single value (trailing text is an error). Schema checks (types, ranges, unknown keys) stay
// with each reader, whose messages name its keys.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace g2l {

/// Parses `text`; `source` names it in errors ("config 'a.json'", "checkpoint 'm.g2l' metadata").
/// Throws g2l::Error: "<source>: invalid JSON at byte N: <reason>" or
/// "<source>: duplicate key '<path>'".
nlohmann::json parse_json_strict(const std::string& text, const std::string& source);
/// The same, keeping the keys in file order (configs echo their input in its order).
nlohmann::ordered_json parse_json_strict_ordered(const std::string& text, const std::string& source);

/// Reads and parses a whole file. Throws g2l::Error naming the file when it is missing, not a
/// regular file, unreadable, or not strict JSON (as parse_json_strict).
nlohmann::json parse_json_file(const std::string& path);

}  // namespace g2l
