// SPDX-License-Identifier: MIT
#include "geometry/mesh_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

#include "core/error.h"

namespace g2l::geom {
namespace {

enum class PlyType { I8, U8, I16, U16, I32, U32, F32, F64 };

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::F32;
    bool is_list = false;
    PlyType count_type = PlyType::U8;
};

struct PlyElement {
    std::string name;
    int64_t count = 0;
    std::vector<PlyProperty> props;
};

bool parse_ply_type(const std::string& s, PlyType* t) {
    static const std::pair<const char*, PlyType> kTable[] = {
        {"char", PlyType::I8},     {"int8", PlyType::I8},     {"uchar", PlyType::U8},
        {"uint8", PlyType::U8},    {"short", PlyType::I16},   {"int16", PlyType::I16},
        {"ushort", PlyType::U16},  {"uint16", PlyType::U16},  {"int", PlyType::I32},
        {"int32", PlyType::I32},   {"uint", PlyType::U32},    {"uint32", PlyType::U32},
        {"float", PlyType::F32},   {"float32", PlyType::F32}, {"double", PlyType::F64},
        {"float64", PlyType::F64}};
    for (const auto& [name, type] : kTable) {
        if (s == name) {
            *t = type;
            return true;
        }
    }
    return false;
}

size_t ply_type_size(PlyType t) {
    switch (t) {
        case PlyType::I8: case PlyType::U8: return 1;
        case PlyType::I16: case PlyType::U16: return 2;
        case PlyType::I32: case PlyType::U32: case PlyType::F32: return 4;
        case PlyType::F64: return 8;
    }
    return 0;
}

bool is_float_type(PlyType t) { return t == PlyType::F32 || t == PlyType::F64; }

std::string read_file(const std::string& path, const char* what) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), what, ": cannot open '", path, "' (missing or unreadable)");
    std::ostringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

/// Sequential value reader over the body of a PLY file (ASCII tokens or little-endian binary).
/// `elem` / `index` name the element being read so truncation errors can say where it happened.
struct PlyReader {
    const std::string& path;
    const std::string& buf;
    size_t pos;
    bool ascii;
    const char* elem = "";
    int64_t index = 0;

    double next(PlyType t) {
        return ascii ? next_ascii() : next_binary(t);
    }

    /// A list's element count: a whole number in [0, bytes left] (each entry takes at least one
    /// byte), so a corrupt count is an error naming it, never an overflowing cast or a long loop.
    int64_t list_count(PlyType t) {
        const double n = next(t);
        const double left = static_cast<double>(buf.size() - std::min(pos, buf.size()));
        G2L_CHECK(std::isfinite(n) && n >= 0 && n <= left && n == std::floor(n), "load_ply: '",
                  path, "': bad list count ", n, " in ", elem, " ", index, " (", left,
                  " data bytes left)");
        return static_cast<int64_t>(n);
    }

    double next_ascii() {
        const char* s = buf.c_str();
        while (pos < buf.size() && std::isspace(static_cast<unsigned char>(s[pos]))) ++pos;
        G2L_CHECK(pos < buf.size(), "load_ply: '", path, "' is truncated: data ended inside ",
                  elem, " ", index);
        char* end = nullptr;
        const double v = std::strtod(s + pos, &end);
        const bool ok = end != s + pos &&
                        (*end == '\0' || std::isspace(static_cast<unsigned char>(*end)));
        if (!ok) {
            const size_t tok_end = std::min(buf.find_first_of(" \t\r\n", pos), buf.size());
            G2L_CHECK(false, "load_ply: '", path, "': malformed number '",
                      buf.substr(pos, std::min<size_t>(tok_end - pos, 40)), "' in ", elem, " ",
                      index);
        }
        pos = static_cast<size_t>(end - s);
        return v;
    }

    double next_binary(PlyType t) {
        const size_t n = ply_type_size(t);
        G2L_CHECK(pos + n <= buf.size(), "load_ply: '", path, "' is truncated: data ended inside ",
                  elem, " ", index, " (byte offset ", pos, ", file size ", buf.size(), ")");
        const char* p = buf.data() + pos;
        pos += n;
        switch (t) {
            case PlyType::I8: { int8_t v; std::memcpy(&v, p, 1); return v; }
            case PlyType::U8: { uint8_t v; std::memcpy(&v, p, 1); return v; }
            case PlyType::I16: { int16_t v; std::memcpy(&v, p, 2); return v; }
            case PlyType::U16: { uint16_t v; std::memcpy(&v, p, 2); return v; }
            case PlyType::I32: { int32_t v; std::memcpy(&v, p, 4); return v; }
            case PlyType::U32: { uint32_t v; std::memcpy(&v, p, 4); return v; }
            case PlyType::F32: { float v; std::memcpy(&v, p, 4); return v; }
            case PlyType::F64: { double v; std::memcpy(&v, p, 8); return v; }
        }
        return 0;
    }
};

/// Parses the rest of a `property <type> <name>` or `property list <count> <type> <name>` line.
PlyProperty parse_property(std::istringstream& ls, const std::string& line, int line_no,
                           const std::string& path) {
    PlyProperty p;
    std::string type;
    ls >> type;
    if (type == "list") {
        std::string ct, vt;
        ls >> ct >> vt >> p.name;
        p.is_list = true;
        G2L_CHECK(parse_ply_type(ct, &p.count_type) && parse_ply_type(vt, &p.type) &&
                      !is_float_type(p.count_type),
                  "load_ply: '", path, "': bad list property on header line ", line_no, ": '",
                  line, "'");
    } else {
        ls >> p.name;
        G2L_CHECK(parse_ply_type(type, &p.type), "load_ply: '", path,
                  "': unknown property type '", type, "' on header line ", line_no);
    }
    G2L_CHECK(!p.name.empty(), "load_ply: '", path, "': property without a name on header line ",
              line_no);
    return p;
}

struct PlyHeader {
    bool ascii = false;
    size_t body = 0;  ///< byte offset of the first data byte
    std::vector<PlyElement> elements;
};

PlyHeader parse_ply_header(const std::string& path, const std::string& buf) {
    PlyHeader h;
    size_t pos = 0;
    int line_no = 0;
    bool have_format = false, have_end = false;
    auto next_line = [&](std::string* line) {
        if (pos >= buf.size()) return false;
        size_t nl = buf.find('\n', pos);
        if (nl == std::string::npos) nl = buf.size();
        *line = buf.substr(pos, nl - pos);
        if (!line->empty() && line->back() == '\r') line->pop_back();
        pos = std::min(nl + 1, buf.size());
        ++line_no;
        return true;
    };
    std::string line;
    G2L_CHECK(next_line(&line) && line == "ply", "load_ply: '", path,
              "' is not a PLY file (first line must be 'ply')");
    while (next_line(&line)) {
        std::istringstream ls(line);
        std::string kw;
        ls >> kw;
        if (kw.empty() || kw == "comment" || kw == "obj_info") continue;
        if (kw == "end_header") {
            have_end = true;
            break;
        }
        if (kw == "format") {
            std::string fmt, ver;
            ls >> fmt >> ver;
            G2L_CHECK(fmt != "binary_big_endian", "load_ply: '", path,
                      "': binary_big_endian PLY is unsupported (convert it to little-endian)");
            G2L_CHECK(fmt == "ascii" || fmt == "binary_little_endian", "load_ply: '", path,
                      "': unknown format '", fmt, "' on header line ", line_no);
            h.ascii = fmt == "ascii";
            have_format = true;
        } else if (kw == "element") {
            PlyElement e;
            long long count = -1;
            ls >> e.name >> count;
            G2L_CHECK(!ls.fail() && count >= 0, "load_ply: '", path, "': bad element line ",
                      line_no, ": '", line, "'");
            e.count = count;
            h.elements.push_back(e);
        } else if (kw == "property") {
            G2L_CHECK(!h.elements.empty(), "load_ply: '", path, "': property before any element "
                      "on header line ", line_no);
            h.elements.back().props.push_back(parse_property(ls, line, line_no, path));
        } else {
            G2L_CHECK(false, "load_ply: '", path, "': bad header line ", line_no, ": '", line,
                      "'");
        }
    }
    G2L_CHECK(have_end, "load_ply: '", path, "': header has no 'end_header' (truncated header)");
    G2L_CHECK(have_format, "load_ply: '", path, "': header has no 'format' line");
    h.body = pos;
    return h;
}

int find_prop(const PlyElement& e, const char* name) {
    for (size_t i = 0; i < e.props.size(); ++i) {
        if (!e.props[i].is_list && e.props[i].name == name) return static_cast<int>(i);
    }
    return -1;
}

void read_vertices(PlyReader& r, const PlyElement& e, Mesh& m) {
    const int ix = find_prop(e, "x"), iy = find_prop(e, "y"), iz = find_prop(e, "z");
    G2L_CHECK(ix >= 0 && iy >= 0 && iz >= 0, "load_ply: '", r.path,
              "': vertex element lacks scalar x, y and z properties");
    const int inx = find_prop(e, "nx"), iny = find_prop(e, "ny"), inz = find_prop(e, "nz");
    const int ir = find_prop(e, "red"), ig = find_prop(e, "green"), ib = find_prop(e, "blue");
    const bool normals = inx >= 0 && iny >= 0 && inz >= 0;
    const bool colors = ir >= 0 && ig >= 0 && ib >= 0;
    m.vertices.resize(e.count, 3);
    if (normals) m.normals.resize(e.count, 3);
    if (colors) m.colors.resize(e.count, 3);
    std::vector<double> val(e.props.size());
    r.elem = "vertex";
    for (int64_t v = 0; v < e.count; ++v) {
        r.index = v;
        for (size_t p = 0; p < e.props.size(); ++p) {
            const PlyProperty& prop = e.props[p];
            if (!prop.is_list) {
                val[p] = r.next(prop.type);
                continue;
            }
            const int64_t n = r.list_count(prop.count_type);  // unknown list: read and drop
            for (int64_t k = 0; k < n; ++k) r.next(prop.type);
        }
        for (int c = 0; c < 3; ++c) {
            const double x = val[c == 0 ? ix : c == 1 ? iy : iz];
            G2L_CHECK(std::isfinite(x) && std::abs(x) <= std::numeric_limits<float>::max(),
                      "load_ply: '", r.path, "': vertex ", v,
                      " has a non-finite or out-of-float-range coordinate (", x, ")");
            m.vertices(v, c) = static_cast<float>(x);
        }
        if (normals) {
            // a normal is a direction: anything outside float range is garbage, stored as 0
            auto nf = [](double x) {
                return std::isfinite(x) && std::abs(x) <= std::numeric_limits<float>::max()
                           ? static_cast<float>(x)
                           : 0.0f;
            };
            m.normals.row(v) << nf(val[inx]), nf(val[iny]), nf(val[inz]);
        }
        if (colors) {
            const int idx[3] = {ir, ig, ib};
            for (int c = 0; c < 3; ++c) {
                double x = val[idx[c]];
                if (is_float_type(e.props[idx[c]].type)) x *= 255.0;
                // clamp in double first: a huge or NaN value must not reach an integer cast
                x = std::isfinite(x) ? std::clamp(x, 0.0, 255.0) : 0.0;
                m.colors(v, c) = static_cast<uint8_t>(std::lround(x));
            }
        }
    }
}

void read_faces(PlyReader& r, const PlyElement& e, Mesh& m) {
    int list = -1;
    for (size_t i = 0; i < e.props.size(); ++i) {
        const PlyProperty& p = e.props[i];
        if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) list = int(i);
    }
    G2L_CHECK(list >= 0, "load_ply: '", r.path,
              "': face element has no 'vertex_indices' / 'vertex_index' list property");
    G2L_CHECK(!is_float_type(e.props[list].type), "load_ply: '", r.path,
              "': face vertex indices must be an integer type");
    const int64_t nv = m.vertices.rows();
    std::vector<int32_t> tri;
    tri.reserve(static_cast<size_t>(e.count) * 3);
    std::vector<int32_t> poly;
    r.elem = "face";
    for (int64_t f = 0; f < e.count; ++f) {
        r.index = f;
        for (size_t p = 0; p < e.props.size(); ++p) {
            const PlyProperty& prop = e.props[p];
            if (!prop.is_list) {
                r.next(prop.type);
                continue;
            }
            const int64_t n = r.list_count(prop.count_type);
            if (static_cast<int>(p) != list) {
                for (int64_t k = 0; k < n; ++k) r.next(prop.type);
                continue;
            }
            G2L_CHECK(n >= 3, "load_ply: '", r.path, "': face ", f, " has ", n,
                      " corners (need at least 3)");
            poly.resize(static_cast<size_t>(n));
            for (int64_t k = 0; k < n; ++k) {
                const double idx = r.next(prop.type);
                G2L_CHECK(idx >= 0 && idx < double(nv), "load_ply: '", r.path, "': face ", f,
                          " index ", idx, " out of range (", nv,
                          " vertices)");
                poly[k] = static_cast<int32_t>(idx);
            }
            for (int64_t k = 1; k + 1 < n; ++k) {  // fan: (0, k, k+1)
                tri.push_back(poly[0]);
                tri.push_back(poly[k]);
                tri.push_back(poly[k + 1]);
            }
        }
    }
    m.faces = Eigen::Map<const Faces>(tri.data(), static_cast<Eigen::Index>(tri.size() / 3), 3);
}

std::string lower_extension(const std::string& path) {
    const size_t dot = path.find_last_of('.');
    const size_t slash = path.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

}  // namespace

Mesh load_ply(const std::string& path) {
    const std::string buf = read_file(path, "load_ply");
    const PlyHeader h = parse_ply_header(path, buf);
    const uint16_t probe = 1;
    uint8_t first = 0;
    std::memcpy(&first, &probe, 1);
    G2L_CHECK(h.ascii || first == 1, "load_ply: '", path,
              "': binary PLY needs a little-endian host");
    Mesh m;
    m.path = path;
    PlyReader r{path, buf, h.body, h.ascii};
    bool have_vertex = false, have_face = false;
    for (const PlyElement& e : h.elements) {
        // Every instance takes at least one byte, so a larger count is a corrupt or truncated
        // file; checking first avoids allocating for an absurd count.
        G2L_CHECK(e.props.empty() || e.count <= static_cast<int64_t>(buf.size() - h.body),
                  "load_ply: '", path, "' declares ", e.count, " ", e.name,
                  " entries but has only ", buf.size() - h.body,
                  " data bytes (truncated file or bad header)");
        if (e.name == "vertex") {
            G2L_CHECK(!have_vertex, "load_ply: '", path, "': two vertex elements");
            read_vertices(r, e, m);
            have_vertex = true;
        } else if (e.name == "face") {
            G2L_CHECK(have_vertex, "load_ply: '", path,
                      "': face element comes before the vertex element");
            G2L_CHECK(!have_face, "load_ply: '", path, "': two face elements");
            read_faces(r, e, m);
            have_face = true;
        } else if (!e.props.empty()) {  // unknown element (edge, material, ...): consume
            // with its declared types (one without properties holds no data, whatever its count)
            r.elem = e.name.c_str();
            for (int64_t i = 0; i < e.count; ++i) {
                r.index = i;
                for (const PlyProperty& p : e.props) {
                    const int64_t n = p.is_list ? r.list_count(p.count_type) : 1;
                    for (int64_t k = 0; k < n; ++k) r.next(p.type);
                }
            }
        }
    }
    G2L_CHECK(have_vertex, "load_ply: '", path, "': no vertex element in the header");
    return m;
}

Mesh load_obj(const std::string& path) {
    const std::string buf = read_file(path, "load_obj");
    std::istringstream in(buf);
    std::vector<float> verts;
    std::vector<int32_t> tri;
    std::vector<int32_t> poly;
    std::string line, kw, tok;
    int line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        std::istringstream ls(line);
        if (!(ls >> kw) || kw[0] == '#') continue;
        if (kw == "v") {
            for (int c = 0; c < 3; ++c) {
                tok.clear();
                ls >> tok;
                char* end = nullptr;
                const double x = std::strtod(tok.c_str(), &end);
                G2L_CHECK(!tok.empty() && *end == '\0' && std::isfinite(x) &&
                              std::abs(x) <= std::numeric_limits<float>::max(),
                          "load_obj: '", path,
                          "' line ", line_no, ": bad vertex coordinate '", tok, "'");
                verts.push_back(static_cast<float>(x));
            }
        } else if (kw == "f") {
            const int64_t nv = static_cast<int64_t>(verts.size() / 3);
            poly.clear();
            while (ls >> tok) {
                char* end = nullptr;
                const long long idx = std::strtoll(tok.c_str(), &end, 10);
                G2L_CHECK(end != tok.c_str() && (*end == '\0' || *end == '/'), "load_obj: '",
                          path, "' line ", line_no, ": bad face corner '", tok, "'");
                const long long zero_based = idx > 0 ? idx - 1 : nv + idx;
                G2L_CHECK(idx != 0 && zero_based >= 0 && zero_based < nv, "load_obj: '", path,
                          "' line ", line_no, ": face index ", idx, " out of range (", nv,
                          " vertices so far)");
                poly.push_back(static_cast<int32_t>(zero_based));
            }
            G2L_CHECK(poly.size() >= 3, "load_obj: '", path, "' line ", line_no, ": face has ",
                      poly.size(), " corners (need at least 3)");
            for (size_t k = 1; k + 1 < poly.size(); ++k) {
                tri.insert(tri.end(), {poly[0], poly[k], poly[k + 1]});
            }
        }
        // vn, vt, o, g, s, usemtl, mtllib, l, ...: not needed for geometry.
    }
    Mesh m;
    m.path = path;
    const auto nv = static_cast<Eigen::Index>(verts.size() / 3);
    m.vertices = Eigen::Map<const Points>(verts.data(), nv, 3);
    m.faces = Eigen::Map<const Faces>(tri.data(), static_cast<Eigen::Index>(tri.size() / 3), 3);
    return m;
}

Mesh load_mesh(const std::string& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".ply") return load_ply(path);
    if (ext == ".obj") return load_obj(path);
    G2L_CHECK(false, "load_mesh: '", path, "' has unsupported extension '", ext,
              "' (expected .ply or .obj)");
    return {};
}

void save_ply(const std::string& path, const Mesh& mesh) {
    const Eigen::Index n = mesh.vertices.rows();
    const bool normals = mesh.normals.rows() > 0, colors = mesh.colors.rows() > 0;
    G2L_CHECK(!normals || mesh.normals.rows() == n, "save_ply: '", path, "': ",
              mesh.normals.rows(), " normals for ", n, " vertices");
    G2L_CHECK(!colors || mesh.colors.rows() == n, "save_ply: '", path, "': ", mesh.colors.rows(),
              " colours for ", n, " vertices");
    for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
        for (int c = 0; c < 3; ++c) {
            G2L_CHECK(mesh.faces(f, c) >= 0 && mesh.faces(f, c) < n, "save_ply: '", path,
                      "': face ", f, " index ", mesh.faces(f, c), " out of range (", n,
                      " vertices)");
        }
    }
    std::ofstream out(path, std::ios::binary);
    G2L_CHECK(out.good(), "save_ply: cannot open '", path, "' for writing");
    out << "ply\nformat binary_little_endian 1.0\ncomment written by g2l\n"
        << "element vertex " << n << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (normals) out << "property float nx\nproperty float ny\nproperty float nz\n";
    if (colors) out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out << "element face " << mesh.faces.rows() << "\nproperty list uchar int vertex_indices\n"
        << "end_header\n";
    std::vector<char> rec;
    for (Eigen::Index i = 0; i < n; ++i) {
        rec.clear();
        auto put = [&rec](const void* p, size_t k) {
            rec.insert(rec.end(), static_cast<const char*>(p), static_cast<const char*>(p) + k);
        };
        for (int c = 0; c < 3; ++c) put(&mesh.vertices(i, c), 4);
        if (normals) for (int c = 0; c < 3; ++c) put(&mesh.normals(i, c), 4);
        if (colors) for (int c = 0; c < 3; ++c) put(&mesh.colors(i, c), 1);
        out.write(rec.data(), static_cast<std::streamsize>(rec.size()));
    }
    for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
        const uint8_t three = 3;
        out.write(reinterpret_cast<const char*>(&three), 1);
        for (int c = 0; c < 3; ++c) {
            const int32_t v = mesh.faces(f, c);
            out.write(reinterpret_cast<const char*>(&v), 4);
        }
    }
    out.close();
    G2L_CHECK(!out.fail(), "save_ply: writing '", path, "' failed (disk full or I/O error)");
}

}  // namespace g2l::geom
