// SPDX-License-Identifier: MIT
#include "data/dataset.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"

namespace fs = std::filesystem;

namespace g2l::data {

namespace {

const char* cv_depth_name(int depth) {
    switch (depth) {
        case CV_8U:
            return "8-bit unsigned";
        case CV_8S:
            return "8-bit signed";
        case CV_16U:
            return "16-bit unsigned";
        case CV_16S:
            return "16-bit signed";
        case CV_32S:
            return "32-bit int";
        case CV_32F:
            return "32-bit float";
        case CV_64F:
            return "64-bit float";
        default:
            return "unknown depth";
    }
}

// imread returns an empty Mat both for a missing and for a corrupt file; check existence first
// so that the message says which.
cv::Mat read_checked(const std::string& path, int flags, const char* what) {
    G2L_CHECK(!path.empty(), "cannot load ", what, ": empty path");
    G2L_CHECK(fs::is_regular_file(path), what, " file not found: '", path, "'");
    cv::Mat m = cv::imread(path, flags);
    G2L_CHECK(!m.empty(), what, " file '", path, "' could not be decoded (truncated or corrupt?)");
    return m;
}

Image to_image(const cv::Mat& m) {
    G2L_ASSERT(m.depth() == CV_8U && m.isContinuous());
    Image img;
    img.w = m.cols;
    img.h = m.rows;
    img.channels = m.channels();
    img.data.assign(m.data, m.data + m.total() * m.elemSize());
    return img;
}

void check_size(const std::string& path, int w, int h, const Frame& frame) {
    if (frame.K.width <= 0 || frame.K.height <= 0) return;
    G2L_CHECK(w == frame.K.width && h == frame.K.height, "image '", path, "' is ", w, "x", h,
              " but the camera of scene ", frame.scene, " image ", frame.image_id, " is ",
              frame.K.width, "x", frame.K.height);
}

uint32_t read_be32(const unsigned char* p) {
    return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | p[3];
}

std::string lower(std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

}  // namespace

std::vector<uint16_t> load_depth_png(const std::string& path, int* w, int* h) {
    G2L_CHECK(w != nullptr && h != nullptr, "load_depth_png('", path, "'): null w/h pointer");
    const cv::Mat m = read_checked(path, cv::IMREAD_UNCHANGED | cv::IMREAD_ANYDEPTH, "depth");
    G2L_CHECK(m.depth() == CV_16U && m.channels() == 1, "depth file '", path,
              "' must be a 16-bit single-channel image, got ", cv_depth_name(m.depth()), " with ",
              m.channels(), " channel(s)");
    *w = m.cols;
    *h = m.rows;
    std::vector<uint16_t> out(static_cast<size_t>(m.cols) * m.rows);
    for (int v = 0; v < m.rows; ++v) {
        const uint16_t* row = m.ptr<uint16_t>(v);
        std::copy(row, row + m.cols, out.begin() + static_cast<size_t>(v) * m.cols);
    }
    return out;
}

Image load_rgb_image(const std::string& path) {
    cv::Mat m = read_checked(path, cv::IMREAD_COLOR, "RGB image");
    cv::Mat rgb;
    cv::cvtColor(m, rgb, cv::COLOR_BGR2RGB);  // OpenCV decodes to BGR
    return to_image(rgb);
}

Image load_mask_image(const std::string& path) {
    const cv::Mat m = read_checked(path, cv::IMREAD_GRAYSCALE, "mask");
    return to_image(m.isContinuous() ? m : m.clone());
}

void save_png(const std::string& path, const Image& image) {
    G2L_CHECK(image.w > 0 && image.h > 0, "save_png('", path, "'): bad size ", image.w, "x",
              image.h);
    G2L_CHECK(image.channels == 1 || image.channels == 3 || image.channels == 4, "save_png('", path,
              "'): channels must be 1, 3 or 4, got ", image.channels);
    const size_t n = static_cast<size_t>(image.w) * image.h * image.channels;
    G2L_CHECK(image.data.size() == n, "save_png('", path, "'): data has ", image.data.size(),
              " bytes, expected w*h*channels = ", n);
    const cv::Mat view(image.h, image.w, CV_8UC(image.channels),
                       const_cast<uint8_t*>(image.data.data()));
    // OpenCV writes BGR(A). Convert into a separate buffer: `view` aliases the caller's data.
    cv::Mat bgr;
    if (image.channels == 1) bgr = view;
    if (image.channels == 3) cv::cvtColor(view, bgr, cv::COLOR_RGB2BGR);
    if (image.channels == 4) cv::cvtColor(view, bgr, cv::COLOR_RGBA2BGRA);
    bool ok = false;
    try {
        ok = cv::imwrite(path, bgr, {cv::IMWRITE_PNG_COMPRESSION, 6});
    } catch (const cv::Exception& e) {
        // OpenCV's text is several lines of its own internals: keep its first line
        std::string why = e.err.empty() ? std::string(e.what()) : e.err;
        why = why.substr(0, why.find('\n'));
        G2L_CHECK(false, "cannot write the image '", path, "': ", why);
    }
    G2L_CHECK(ok, "cannot write the image '", path, "' (", std::strerror(errno ? errno : EIO),
              ")");
}

void save_depth_png(const std::string& path, const uint16_t* depth, int w, int h) {
    G2L_CHECK(depth != nullptr && w > 0 && h > 0, "save_depth_png('", path, "'): bad input ", w,
              "x", h, depth ? "" : " (null data)");
    const cv::Mat view(h, w, CV_16UC1, const_cast<uint16_t*>(depth));
    bool ok = false;
    try {
        ok = cv::imwrite(path, view, {cv::IMWRITE_PNG_COMPRESSION, 6});
    } catch (const cv::Exception& e) {
        G2L_CHECK(false, "save_depth_png: cannot write '", path, "': ", e.what());
    }
    G2L_CHECK(ok, "save_depth_png: cannot write '", path, "'");
}

void image_size(const std::string& path, int* w, int* h) {
    G2L_CHECK(w != nullptr && h != nullptr, "image_size('", path, "'): null w/h pointer");
    G2L_CHECK(fs::is_regular_file(path), "image file not found: '", path, "'");
    // PNG: 8-byte signature, then the IHDR chunk (length, "IHDR", width, height big-endian).
    unsigned char head[24] = {};
    std::ifstream f(path, std::ios::binary);
    f.read(reinterpret_cast<char*>(head), sizeof(head));
    static const unsigned char kPngSig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (std::equal(kPngSig, kPngSig + 8, head)) {
        G2L_CHECK(f.gcount() == 24 && std::equal(head + 12, head + 16, "IHDR"), "PNG file '", path,
                  "' is truncated or has no IHDR chunk");
        *w = static_cast<int>(read_be32(head + 16));
        *h = static_cast<int>(read_be32(head + 20));
        G2L_CHECK(*w > 0 && *h > 0, "PNG file '", path, "' has a bad size ", *w, "x", *h);
        return;
    }
    const cv::Mat m = read_checked(path, cv::IMREAD_UNCHANGED | cv::IMREAD_ANYDEPTH, "image");
    *w = m.cols;
    *h = m.rows;
}

// ---- Dataset -------------------------------------------------------------------------------

// Meshes keyed by object id; std::map nodes never move, so returned references stay valid.
struct Dataset::MeshCache {
    std::mutex mutex;
    std::map<int, geom::Mesh> meshes;
};

Dataset::Dataset(std::string name, std::string root, std::vector<Frame> frames,
                 std::map<int, ObjectModel> models)
    : name_(std::move(name)),
      root_(std::move(root)),
      frames_(std::move(frames)),
      models_(std::move(models)),
      cache_(std::make_shared<MeshCache>()) {}

const ObjectModel& Dataset::model(int obj_id) const {
    const auto it = models_.find(obj_id);
    if (it == models_.end()) {
        std::string known;
        for (const auto& kv : models_)
            known += (known.empty() ? "" : ", ") + std::to_string(kv.first);
        G2L_CHECK(false, "dataset '", name_, "' (", root_, ") has no object id ", obj_id,
                  "; known ids: {", known, "}");
    }
    return it->second;
}

const geom::Mesh& Dataset::load_model_mesh(int obj_id) const {
    const ObjectModel& m = model(obj_id);
    G2L_CHECK(cache_ != nullptr, "load_model_mesh on a default-constructed Dataset");
    std::lock_guard<std::mutex> lock(cache_->mutex);
    auto it = cache_->meshes.find(obj_id);
    if (it == cache_->meshes.end()) {
        // Loading under the lock keeps one copy per object; meshes load once per process.
        // Meshes and models_info come from users: a mesh in metres or a diameter off by 10
        // would move every metric silently (ADD thresholds are 10 % of the diameter).
        geom::Mesh mesh = geom::load_mesh(m.mesh_path);
        geom::check_mesh_units(mesh, &m.info, cat("the models_info of dataset '", root_,
                                                  "' (object ", obj_id, ")"));
        it = cache_->meshes.emplace(obj_id, std::move(mesh)).first;
    }
    return it->second;
}

std::vector<uint16_t> Dataset::load_depth(const Frame& frame, int* w, int* h) const {
    G2L_CHECK(!frame.depth_path.empty(), "dataset '", name_, "' has no depth image for scene ",
              frame.scene, " image ", frame.image_id);
    std::vector<uint16_t> d = load_depth_png(frame.depth_path, w, h);
    check_size(frame.depth_path, *w, *h, frame);
    return d;
}

std::vector<float> Dataset::load_depth_mm(const Frame& frame, int* w, int* h) const {
    const std::vector<uint16_t> raw = load_depth(frame, w, h);
    std::vector<float> mm(raw.size());
    for (size_t i = 0; i < raw.size(); ++i) {
        mm[i] = static_cast<float>(raw[i] * frame.depth_scale);
    }
    return mm;
}

Image Dataset::load_rgb(const Frame& frame) const {
    G2L_CHECK(!frame.rgb_path.empty(), "dataset '", name_, "' has no RGB image for scene ",
              frame.scene, " image ", frame.image_id);
    Image img = load_rgb_image(frame.rgb_path);
    check_size(frame.rgb_path, img.w, img.h, frame);
    return img;
}

Image Dataset::load_mask(const Frame& frame, const Instance& instance) const {
    G2L_CHECK(!instance.mask_visib_path.empty(), "dataset '", name_, "' has no visible mask for ",
              "scene ", frame.scene, " image ", frame.image_id, " instance ",
              instance.index_in_frame, " (obj ", instance.obj_id, ")");
    Image img = load_mask_image(instance.mask_visib_path);
    check_size(instance.mask_visib_path, img.w, img.h, frame);
    return img;
}

// ---- dataset name conventions --------------------------------------------------------------

namespace {
// The family of a dataset name: lower case, up to the first '_' or '-' ("ycbv_mini" -> "ycbv").
std::string family(const std::string& name) {
    const std::string s = lower(name);
    return s.substr(0, s.find_first_of("_-"));
}
}  // namespace

std::vector<int> symmetric_convention(const std::string& convention) {
    const std::string f = lower(convention);
    if (f == "ycbv") return {13, 16, 19, 20, 21};
    if (f == "lm" || f == "lmo" || f == "linemod") return {10, 11};
    G2L_CHECK(false, "no symmetric-object convention '", convention,
              "' (known: ycbv, lm, lmo, linemod; or give the object ids)");
    return {};
}

std::string default_object_name(const std::string& dataset_name, int obj_id) {
    static const char* kLinemod[] = {"ape",  "benchvise",   "bowl",    "camera", "can",
                                     "cat",  "cup",         "driller", "duck",   "eggbox",
                                     "glue", "holepuncher", "iron",    "lamp",   "phone"};
    const std::string f = family(dataset_name);
    if ((f == "lm" || f == "lmo" || f == "linemod") && obj_id >= 1 && obj_id <= 15) {
        return kLinemod[obj_id - 1];
    }
    return "";
}

}  // namespace g2l::data
