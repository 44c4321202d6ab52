// SPDX-License-Identifier: MIT
// A parser for the small YAML subset of the Linemod_preprocessed annotation files (gt.yml,
// info.yml). It is not a general YAML parser: it reads integer-keyed top-level blocks whose
// content is either one flat map or a list of flat maps with numeric values.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace g2l::data {

/// A numeric YAML value: a scalar (`depth_scale: 1.0`, numbers.size() == 1, is_list false) or a
/// flow list (`cam_K: [572.4, 0.0, ...]`, is_list true). `line` is the 1-based source line.
struct YamlValue {
    std::vector<double> numbers;
    bool is_list = false;
    int line = 0;
};

/// A flat map `key: value` of one block or one list item.
struct YamlRecord {
    std::map<std::string, YamlValue> fields;
    int line = 0;  ///< line where the record starts
};

/// The content of one top-level `<int>:` key: a list of records (`- key: value` items) or one
/// record (is_list false, records.size() == 1). An empty block (`3: []`, `3: {}` or nothing
/// indented below) has no records.
struct YamlBlock {
    bool is_list = false;
    std::vector<YamlRecord> records;
    int line = 0;
};

/// Parses `path`, accepting exactly:
///   <int>:                     top-level key at column 0 (optionally `<int>: []` or `<int>: {}`)
///   - <key>: <value>           starts a list item (any indentation, also column 0)
///     <key>: <value>           continues the current item or block (indented)
/// where <value> is a number or a `[n, n, ...]` flow list that may span lines. Blank lines and
/// `#` comments are skipped. Throws g2l::Error naming the file and line (and the text found) for
/// a missing file, any other construct, a bad number, a duplicated key or an unterminated list.
std::map<int, YamlBlock> parse_int_keyed_yaml(const std::string& path);

/// The field `key` of `rec` (from `file`) holding exactly `n` numbers (n == 1: a scalar or a
/// one-element list). Throws g2l::Error naming the file, line and key when it is missing or has
/// another length.
const std::vector<double>& yaml_numbers(const YamlRecord& rec, const std::string& key, size_t n,
                                        const std::string& file);

}  // namespace g2l::data
