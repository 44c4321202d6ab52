// SPDX-License-Identifier: MIT
#include "geometry/model_info.h"
#include "core/json.h"
#include "core/json_reader.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <vector>

#include "core/error.h"

namespace g2l::geom {
namespace {

const char* const kInfoKeys[7] = {"diameter", "min_x", "min_y", "min_z",
                                  "size_x",   "size_y", "size_z"};

ModelInfo info_from_values(const double v[7]) {
    ModelInfo m;
    m.diameter = v[0];
    m.min = Eigen::Vector3d(v[1], v[2], v[3]);
    m.size = Eigen::Vector3d(v[4], v[5], v[6]);
    return m;
}

/// Exact largest pairwise distance of the N x 3 points v; c is any centre (the box centre).
/// 1. A lower bound L from a "double normal" walk: jump to the farthest point a few times.
/// 2. With d_i = |p_i - c| and r = max d_i, |p_i - p_j| <= d_i + d_j <= d_i + r, so points with
///    d_i + r < L cannot be in the diameter pair and are dropped.
/// 3. The survivors are sorted by d_i (descending) and compared pairwise; the inner loop stops
///    as soon as d_i + d_j cannot beat the best pair found, as every later j has a smaller d_j.
/// Skipped pairs are provably no longer than a pair already seen, so the result is the exact
/// maximum whatever the thread count. A tiny slack covers rounding in the bounds.
double exact_diameter(const Points& v, const Eigen::Vector3d& c) {
    const int64_t n = v.rows();
    std::vector<double> p(static_cast<size_t>(n) * 3), dc(static_cast<size_t>(n));
    double r = 0;
    for (int64_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) p[3 * i + k] = v(i, k);
        dc[i] = std::sqrt((p[3 * i] - c[0]) * (p[3 * i] - c[0]) +
                          (p[3 * i + 1] - c[1]) * (p[3 * i + 1] - c[1]) +
                          (p[3 * i + 2] - c[2]) * (p[3 * i + 2] - c[2]));
        r = std::max(r, dc[i]);
    }
    auto dist2 = [&p](int64_t a, int64_t b) {
        const double x = p[3 * a] - p[3 * b], y = p[3 * a + 1] - p[3 * b + 1],
                     z = p[3 * a + 2] - p[3 * b + 2];
        return x * x + y * y + z * z;
    };
    double lower2 = 0;
    int64_t a = 0;
    for (int iter = 0; iter < 5; ++iter) {
        int64_t far = a;
        double far2 = 0;
        for (int64_t j = 0; j < n; ++j) {
            const double d = dist2(a, j);
            if (d > far2) {
                far2 = d;
                far = j;
            }
        }
        if (far2 <= lower2) break;
        lower2 = far2;
        a = far;
    }
    const double slack = 1e-9 * (r + 1.0);
    const double lower = std::sqrt(lower2);
    std::vector<int64_t> cand;
    for (int64_t i = 0; i < n; ++i) {
        if (dc[i] + r + slack >= lower) cand.push_back(i);
    }
    std::sort(cand.begin(), cand.end(), [&dc](int64_t x, int64_t y) {
        return dc[x] != dc[y] ? dc[x] > dc[y] : x < y;
    });
    const int64_t m = static_cast<int64_t>(cand.size());
    double best2 = lower2;
#pragma omp parallel for reduction(max : best2) schedule(dynamic, 16)
    for (int64_t i = 0; i < m; ++i) {
        double local = std::max(best2, lower2);
        const int64_t pi = cand[i];
        for (int64_t j = i + 1; j < m; ++j) {
            const double bound = dc[pi] + dc[cand[j]] + slack;
            if (bound * bound < local) break;
            local = std::max(local, dist2(pi, cand[j]));
        }
        best2 = std::max(best2, local);
    }
    return std::sqrt(best2);
}

int parse_obj_id(const std::string& s, const std::string& path, const std::string& where) {
    char* end = nullptr;
    const long id = std::strtol(s.c_str(), &end, 10);
    G2L_CHECK(!s.empty() && *end == '\0' && id >= 0 && id <= 1000000, path, ": ", where,
              ": object id '", s, "' is not a non-negative integer");
    return static_cast<int>(id);
}

}  // namespace

ModelInfo compute_model_info(const Points& vertices) {
    const Eigen::Index n = vertices.rows();
    G2L_CHECK(n > 0, "compute_model_info: no vertices");
    for (Eigen::Index i = 0; i < n; ++i) {
        G2L_CHECK(vertices.row(i).allFinite(), "compute_model_info: vertex ", i,
                  " is not finite (", vertices(i, 0), ", ", vertices(i, 1), ", ", vertices(i, 2),
                  ")");
    }
    ModelInfo info;
    const Eigen::Vector3d lo = vertices.colwise().minCoeff().cast<double>().transpose();
    const Eigen::Vector3d hi = vertices.colwise().maxCoeff().cast<double>().transpose();
    info.min = lo;
    info.size = hi - lo;
    info.diameter = exact_diameter(vertices, 0.5 * (lo + hi));
    return info;
}

namespace {

// What a ratio declared / measured diameter says about units.
std::string unit_hint(double r) {
    if (r > 300 && r < 3000)
        return "; the mesh looks like metres: scale its vertices by 1000 (meshes are in millimetres)";
    if (r > 1.0 / 3000 && r < 1.0 / 300)
        return "; the mesh looks like micrometres or the diameter like metres: meshes and "
               "diameters are in millimetres";
    if ((r > 5 && r < 20) || (r > 0.05 && r < 0.2))
        return "; a factor of 10 is a centimetre / millimetre slip in the mesh or the models_info";
    return "; fix the models_info entry (g2l_render writes one measured from the meshes)";
}

}  // namespace

ModelInfo check_mesh_units(const Mesh& mesh, const ModelInfo* declared,
                           const std::string& declared_in) {
    G2L_CHECK(mesh.vertices.rows() > 0, "mesh '", mesh.path, "' has no vertices");
    const ModelInfo measured = compute_model_info(mesh.vertices);
    if (declared) {
        const double r = declared->diameter / measured.diameter;
        G2L_CHECK(std::abs(r - 1) <= 0.05, "mesh '", mesh.path, "' measures ", measured.diameter,
                  " mm across (its two farthest vertices) but ", declared_in, " declares diameter ",
                  declared->diameter, " mm (", r, " x)", unit_hint(r));
    } else {
        G2L_CHECK(measured.diameter >= kMetreMeshBelow, "mesh '", mesh.path, "' is only ", measured.diameter,
                  " units across: meshes are in millimetres, and this one looks like metres — "
                  "scale its vertices by 1000");
    }
    return measured;
}

std::map<int, ModelInfo> load_models_info_json(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "load_models_info_json: cannot open '", path, "'");
    std::ostringstream ss;
    ss << f.rdbuf();
    const nlohmann::json j = parse_json_strict(ss.str(), "load_models_info_json: '" + path + "'");
    JsonReader top(j, "load_models_info_json: '" + path + "'");
    std::map<int, ModelInfo> out;
    top.members([&](const std::string& key, const nlohmann::json& e, const std::string&) {
        const int id = parse_obj_id(key, path, "key");
        JsonReader r(e, top.source(), key);
        double v[7];
        for (int k = 0; k < 7; ++k) {
            r.require(kInfoKeys[k]);
            r.num(kInfoKeys[k], v[k]);
        }
        G2L_CHECK(v[0] > 0, top.source(), ": '", r.at("diameter"), "' must be > 0, got ", v[0]);
        ModelInfo m = info_from_values(v);
        // BOP: a list of 4x4 transforms / of {axis, offset}; any entry makes the object
        // symmetric for the metrics (ADD-S).
        for (const char* sym : {"symmetries_discrete", "symmetries_continuous"}) {
            if (const nlohmann::json* x = r.get(sym)) {
                G2L_CHECK(x->is_array(), top.source(), ": '", r.at(sym),
                          "' must be an array, got ", x->type_name());
                if (!x->empty()) m.symmetric = true;
            }
        }
        r.finish();
        out[id] = m;
    });
    return out;
}

std::map<int, ModelInfo> load_models_info_yml(const std::string& path) {
    std::ifstream f(path);
    G2L_CHECK(f.good(), "load_models_info_yml: cannot open '", path, "'");
    std::map<int, ModelInfo> out;
    std::string line;
    int line_no = 0;
    while (std::getline(f, line)) {
        ++line_no;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        const size_t first = line.find_first_not_of(" \t");
        if (first == std::string::npos || line[first] == '#') continue;
        const std::string where = cat("line ", line_no);
        const size_t colon = line.find(':');
        const size_t open = line.find('{'), close = line.rfind('}');
        G2L_CHECK(colon != std::string::npos && open != std::string::npos &&
                      close != std::string::npos && colon < open && open < close,
                  "load_models_info_yml: '", path, "' ", where,
                  ": expected '<id>: {key: value, ...}', got '", line, "'");
        std::string id_str = line.substr(first, colon - first);
        id_str.erase(id_str.find_last_not_of(" \t") + 1);
        const int id = parse_obj_id(id_str, path, where);
        G2L_CHECK(!out.count(id), "load_models_info_yml: '", path, "' ", where, ": object id ",
                  id, " appears twice");
        double v[7];
        bool have[7] = {false, false, false, false, false, false, false};
        std::stringstream body(line.substr(open + 1, close - open - 1));
        std::string item;
        while (std::getline(body, item, ',')) {
            const size_t c = item.find(':');
            G2L_CHECK(c != std::string::npos, "load_models_info_yml: '", path, "' ", where,
                      ": entry '", item, "' has no ':'");
            std::string key = item.substr(0, c);
            key.erase(0, key.find_first_not_of(" \t"));
            key.erase(key.find_last_not_of(" \t") + 1);
            std::string val = item.substr(c + 1);
            val.erase(0, val.find_first_not_of(" \t"));
            val.erase(val.find_last_not_of(" \t") + 1);
            char* end = nullptr;
            const double x = std::strtod(val.c_str(), &end);
            const bool ok = !val.empty() && *end == '\0';
            G2L_CHECK(ok && std::isfinite(x), "load_models_info_yml: '", path, "' ", where,
                      ": bad number '", val, "' for key '", key, "'");
            for (int k = 0; k < 7; ++k) {
                if (key == kInfoKeys[k]) {
                    v[k] = x;
                    have[k] = true;
                }
            }
        }
        for (int k = 0; k < 7; ++k) {
            G2L_CHECK(have[k], "load_models_info_yml: '", path, "' ", where, ": object ", id,
                      " has no '", kInfoKeys[k], "'");
        }
        G2L_CHECK(v[0] > 0, "load_models_info_yml: '", path, "' ", where, ": object ", id,
                  " diameter must be > 0, got ", v[0]);
        out[id] = info_from_values(v);
    }
    return out;
}

}  // namespace g2l::geom
