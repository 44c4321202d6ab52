// SPDX-License-Identifier: MIT
#include "train/detector_augment.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>

#include "core/error.h"
#include "data/bop.h"
#include "data/draw.h"

namespace g2l::train {

namespace fs = std::filesystem;

void object_tone(std::vector<uint8_t>& rgb, const std::vector<uint16_t>& groups, int w, int h,
                 double prob, Rng& rng) {
    G2L_CHECK(w > 0 && h > 0, "object_tone: bad image size ", w, " x ", h);
    const size_t n = size_t(w) * size_t(h);
    G2L_CHECK(rgb.size() == n * 3 && groups.size() == n, "object_tone: ", rgb.size(),
              " colour values and ", groups.size(), " group ids for a ", w, " x ", h, " image");
    G2L_CHECK(std::isfinite(prob) && prob >= 0 && prob <= 1, "object_tone: prob must be in [0, 1], got ",
              prob);
    if (prob == 0) return;
    // Mean colour of every group present, in one pass.
    std::map<uint16_t, std::array<double, 4>> mean;
    for (size_t i = 0; i < n; ++i) {
        if (groups[i] == 0) continue;
        auto& m = mean[groups[i]];
        for (int k = 0; k < 3; ++k) m[size_t(k)] += rgb[i * 3 + size_t(k)];
        m[3] += 1;
    }
    struct Tone {
        float mean[3], contrast, gain[3], sat;
    };
    std::map<uint16_t, Tone> tone;  // the groups drawn to change, in id order (reproducible)
    for (auto& [g, m] : mean) {
        if (rng.uniform() >= prob) continue;
        Tone t;
        for (int k = 0; k < 3; ++k) t.mean[k] = float(m[size_t(k)] / m[3]);
        t.contrast = float(rng.uniform(0.4, 1.0));
        const double bright = rng.uniform(0.5, 1.2);
        for (float& gk : t.gain) gk = float(bright * rng.uniform(0.85, 1.15));
        t.sat = float(rng.uniform(0.5, 1.3));
        tone[g] = t;
    }
    if (tone.empty()) return;
    for (size_t i = 0; i < n; ++i) {
        if (groups[i] == 0) continue;
        const auto it = tone.find(groups[i]);
        if (it == tone.end()) continue;
        const Tone& t = it->second;
        float v[3];
        for (int k = 0; k < 3; ++k)
            v[k] = (t.mean[k] + t.contrast * (float(rgb[i * 3 + size_t(k)]) - t.mean[k])) * t.gain[k];
        const float lum = (v[0] + v[1] + v[2]) / 3;
        for (int k = 0; k < 3; ++k)
            rgb[i * 3 + size_t(k)] = uint8_t(std::clamp(lum + t.sat * (v[k] - lum) + 0.5f, 0.f, 255.f));
    }
}

// Colour gain / brightness, grey, Gaussian noise, 3x3 box blur: in place.
void augment(std::vector<uint8_t>& rgb, int w, int h, const DetectorTrainConfig& c, Rng& rng) {
    float gain[3], bias = float(rng.uniform(-c.color_jitter, c.color_jitter) * 255 * 0.5);
    const float g0 = float(rng.uniform(1 - c.color_jitter, 1 + c.color_jitter));
    for (float& g : gain) g = g0 * float(rng.uniform(1 - 0.5 * c.color_jitter, 1 + 0.5 * c.color_jitter));
    const bool gray = rng.uniform() < c.gray_prob;
    const float noise = float(rng.uniform(0, c.noise_std));
    const size_t n = size_t(w) * size_t(h);
    for (size_t i = 0; i < n; ++i) {
        float v[3];
        for (int k = 0; k < 3; ++k) v[k] = float(rgb[i * 3 + size_t(k)]) * gain[k] + bias;
        if (gray) v[0] = v[1] = v[2] = (v[0] + v[1] + v[2]) / 3;
        for (int k = 0; k < 3; ++k) {
            const float x = v[k] + (noise > 0 ? noise * float(rng.normal()) : 0.f);
            rgb[i * 3 + size_t(k)] = uint8_t(std::clamp(x, 0.f, 255.f));
        }
    }
    if (rng.uniform() < c.blur_prob) {
        std::vector<uint8_t> src = rgb;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int k = 0; k < 3; ++k) {
                    int s = 0, m = 0;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int yy = y + dy, xx = x + dx;
                            if (yy < 0 || yy >= h || xx < 0 || xx >= w) continue;
                            s += src[(size_t(yy) * size_t(w) + size_t(xx)) * 3 + size_t(k)];
                            ++m;
                        }
                    rgb[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(k)] = uint8_t(s / m);
                }
    }
}

// A "dead leaves" clutter texture (random rectangles and discs of random colours, sizes spread
// over a log scale, painted back to front) replaces every pixel that shows no object (keep == 0):
// real frames show cluttered desks, the renders a plain table.
void clutter_background(std::vector<uint8_t>& rgb, const std::vector<uint8_t>& keep, int w,
                        int h, Rng& rng) {
    std::vector<uint8_t> bg(size_t(w) * size_t(h) * 3);
    for (size_t i = 0; i < bg.size(); i += 3) {
        bg[i] = uint8_t(rng.below(256));
        bg[i + 1] = bg[i];
        bg[i + 2] = bg[i];
    }
    const int shapes = int(rng.randint(40, 160));
    for (int s = 0; s < shapes; ++s) {
        const double size = std::exp(rng.uniform(std::log(3.0), std::log(0.6 * std::max(w, h))));
        const double cx = rng.uniform(-0.1 * w, 1.1 * w), cy = rng.uniform(-0.1 * h, 1.1 * h);
        const double aspect = std::exp(rng.uniform(-1.2, 1.2));
        const double rw = size * aspect * 0.5, rh = size / aspect * 0.5;
        const bool disc = rng.uniform() < 0.5;
        uint8_t col[3];
        const double sat = rng.uniform();
        const double base = rng.uniform(0, 255);
        for (uint8_t& c : col) c = uint8_t(std::clamp(base + sat * rng.uniform(-128, 128), 0.0, 255.0));
        for_each_shape_pixel(w, h, cx, cy, rw, rh, disc, [&](size_t i) {
            uint8_t* p = &bg[i * 3];
            p[0] = col[0], p[1] = col[1], p[2] = col[2];
        });
    }
    for (size_t i = 0; i < size_t(w) * size_t(h); ++i)
        if (keep[i] == 0)
            for (int k = 0; k < 3; ++k) rgb[i * 3 + size_t(k)] = bg[i * 3 + size_t(k)];
}

// A random crop of a random photograph (35-100% of its width, the input's aspect ratio,
// mirrored half the time), resampled bilinearly, replaces every pixel with keep == 0.
void photo_background(std::vector<uint8_t>& rgb, const std::vector<uint8_t>& keep, int w, int h,
                      const std::vector<data::Image>& photos, Rng& rng) {
    const data::Image& p = photos[size_t(rng.below(photos.size()))];
    const double aspect = double(h) / double(w);
    double cw = rng.uniform(0.35, 1.0) * p.w;
    if (cw * aspect > p.h) cw = p.h / aspect;
    const double ch = cw * aspect;
    const double x0 = rng.uniform(0, std::max(0.0, p.w - cw)), y0 = rng.uniform(0, std::max(0.0, p.h - ch));
    const bool flip = rng.uniform() < 0.5;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (keep[i]) continue;
            const double fx = (flip ? (w - 1 - x) : x) + 0.5, fy = y + 0.5;
            const double sx = std::clamp(x0 + fx * cw / w - 0.5, 0.0, double(p.w - 1));
            const double sy = std::clamp(y0 + fy * ch / h - 0.5, 0.0, double(p.h - 1));
            const int ix = std::min(int(sx), p.w - 2);  // photos are >= 16 px (load_photos)
            const int iy = std::min(int(sy), p.h - 2);
            const double ax = std::clamp(sx - ix, 0.0, 1.0), ay = std::clamp(sy - iy, 0.0, 1.0);
            const int ix1 = std::min(ix + 1, p.w - 1), iy1 = std::min(iy + 1, p.h - 1);
            for (int k = 0; k < 3; ++k) {
                auto at = [&](int xx, int yy) {
                    return double(p.data[(size_t(yy) * size_t(p.w) + size_t(xx)) * 3 + size_t(k)]);
                };
                const double v = (1 - ay) * ((1 - ax) * at(ix, iy) + ax * at(ix1, iy)) +
                                 ay * ((1 - ax) * at(ix, iy1) + ax * at(ix1, iy1));
                rgb[i * 3 + size_t(k)] = uint8_t(std::clamp(v + 0.5, 0.0, 255.0));
            }
        }
}

// Every .png / .jpg file directly in each directory, as RGB (sorted: the training is
// reproducible). Throws naming the directory when one is missing or holds no image.
std::vector<data::Image> load_photos(const std::vector<std::string>& dirs) {
    std::vector<data::Image> out;
    for (const std::string& d : dirs) {
        G2L_CHECK(fs::is_directory(d), "augment.backgrounds: '", d, "' is not a directory");
        std::vector<std::string> files;
        for (const auto& e : fs::directory_iterator(d)) {
            std::string ext = e.path().extension().string();
            for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
            if (e.is_regular_file() && (ext == ".png" || ext == ".jpg" || ext == ".jpeg"))
                files.push_back(e.path().string());
        }
        G2L_CHECK(!files.empty(), "augment.backgrounds: '", d, "' holds no .png or .jpg image");
        std::sort(files.begin(), files.end());
        for (const std::string& f : files) {
            out.push_back(data::load_rgb_image(f));
            G2L_CHECK(out.back().w >= 16 && out.back().h >= 16, "augment.backgrounds: '", f,
                      "' is too small (", out.back().w, " x ", out.back().h, ")");
        }
    }
    return out;
}

// Vertex colours for a distractor mesh without any: a base colour (half the time a grey or
// white, else a saturated one) with a linear gradient along a random axis and per-vertex noise,
// so a distractor looks like a painted or printed object, not a flat silhouette.
void paint_distractor(geom::Mesh& m, Rng& rng) {
    double base[3];
    if (rng.uniform() < 0.5) {
        const double g = rng.uniform(90, 250);
        for (double& b : base) b = g + rng.uniform(-10, 10);
    } else {
        for (double& b : base) b = rng.uniform(0, 255);
    }
    Eigen::Vector3d axis(rng.normal(), rng.normal(), rng.normal());
    axis.normalize();
    double lo = 1e30, hi = -1e30;
    for (int i = 0; i < m.vertices.rows(); ++i) {
        const double t = m.vertices.row(i).cast<double>().dot(axis.transpose());
        lo = std::min(lo, t), hi = std::max(hi, t);
    }
    const double amp = rng.uniform(0, 60);
    m.colors.resize(m.vertices.rows(), 3);
    for (int i = 0; i < m.vertices.rows(); ++i) {
        const double t = (m.vertices.row(i).cast<double>().dot(axis.transpose()) - lo) /
                         std::max(1e-9, hi - lo);
        for (int k = 0; k < 3; ++k)
            m.colors(i, k) = uint8_t(std::clamp(base[k] + amp * (t - 0.5) + rng.uniform(-8, 8), 0.0, 255.0));
    }
}

}  // namespace g2l::train
