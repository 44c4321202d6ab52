// SPDX-License-Identifier: MIT
// Your own objects (train/own_objects.h): a folder of meshes of any names and units becomes a
// BOP models folder with ids, names, diameters and symmetries; bad folders are named.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/bop.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"
#include "testing.h"
#include "train/own_objects.h"

using namespace g2l;
using Catch::Contains;
namespace fs = std::filesystem;

namespace {

const std::string kMini = testing::fixture_dir() + "/ycbv_mini/models";

// The fixture's gelatin box (object 8) in metres under another name, and the mug as it is.
std::string user_folder(const std::string& tag) {
    const std::string dir = testing::temp_dir(tag);
    geom::Mesh m = geom::load_mesh(kMini + "/obj_000008.ply");
    m.vertices /= 1000.f;
    geom::save_ply(dir + "/Gelatin Box.ply", m);
    fs::copy_file(kMini + "/obj_000014.ply", dir + "/obj_000014.ply");
    return dir;
}

}  // namespace

TEST_CASE("own objects: any names and metres become a BOP models folder with names and symmetries",
          "[train][own]") {
    const std::string dir = user_folder("own_models");
    const std::string root = testing::temp_dir("own_models_out");
    std::vector<std::string> notes;
    const auto objs = train::prepare_own_models(dir, root, &notes);
    REQUIRE(objs.size() == 2);
    // obj_000014 keeps its id; the other name takes the smallest free one.
    CHECK(objs[0].obj_id == 1);
    CHECK(objs[0].name == "Gelatin Box");
    CHECK(objs[0].converted_from_m);
    CHECK(objs[1].obj_id == 14);
    CHECK_FALSE(objs[1].converted_from_m);
    REQUIRE(notes.size() == 1);
    CHECK_THAT(notes[0], Contains("Gelatin Box.ply") && Contains("metres") && Contains("1000"));
    // The diameters are the millimetre meshes' (the fixture's models_info: 8 -> 114.0 mm).
    const auto declared = geom::load_models_info_json(kMini + "/models_info.json");
    CHECK(objs[0].diameter_mm == Approx(declared.at(8).diameter).epsilon(0.01));
    CHECK(objs[1].diameter_mm == Approx(declared.at(14).diameter).epsilon(0.01));
    // A box has its geometric symmetries, declared in models_info.json; the mug has none.
    CHECK(objs[0].symmetries > 1);
    CHECK(objs[1].symmetries == 1);
    const auto info = geom::load_models_info_json(root + "/models/models_info.json");
    CHECK(info.at(1).symmetric);
    CHECK_FALSE(info.at(14).symmetric);
    // A BOP root: the dataset reader takes it, with the names.
    const data::Dataset ds = data::open_bop_models(root);
    REQUIRE(ds.models().size() == 2);
    CHECK(ds.model(1).name == "Gelatin Box");
    CHECK(ds.model(1).info.diameter == Approx(objs[0].diameter_mm));
    CHECK(geom::load_mesh(root + "/models/obj_000001.ply").vertices.maxCoeff() > 10);
}

TEST_CASE("own objects: bad folders are named, never half-used", "[train][own]") {
    const std::string root = testing::temp_dir("own_bad_out");
    const std::string empty = testing::temp_dir("own_empty");
    REQUIRE_THROWS_WITH(train::prepare_own_models(empty, root, nullptr),
                        Contains(empty) && Contains("no .ply or .obj mesh"));
    REQUIRE_THROWS_WITH(train::prepare_own_models(empty + "/nope", root, nullptr),
                        Contains("is not a folder"));
    // Two files claiming one id.
    const std::string twice = testing::temp_dir("own_twice");
    fs::copy_file(kMini + "/obj_000008.ply", twice + "/obj_000008.ply");
    {
        std::ofstream f(twice + "/obj_000008.obj");
        f << "v 0 0 0\nv 100 0 0\nv 0 100 0\nf 1 2 3\n";
    }
    REQUIRE_THROWS_WITH(train::prepare_own_models(twice, root, nullptr),
                        Contains("both give object 8"));
    // A part under 1 cm even in metres: refused, naming the file.
    const std::string tiny = testing::temp_dir("own_tiny");
    {
        std::ofstream f(tiny + "/speck.obj");
        f << "v 0 0 0\nv 0.000001 0 0\nv 0 0.000001 0\nf 1 2 3\n";
    }
    REQUIRE_THROWS_WITH(train::prepare_own_models(tiny, root, nullptr),
                        Contains("speck.obj") && Contains("units across"));
    // A corrupt mesh names its file.
    const std::string bad = testing::temp_dir("own_corrupt");
    {
        std::ofstream f(bad + "/part.ply");
        f << "ply\nformat ascii 1.0\nelement vertex 3\n";
    }
    REQUIRE_THROWS_WITH(train::prepare_own_models(bad, root, nullptr), Contains("part.ply"));
}

TEST_CASE("own objects: the whole road on a tiny budget writes both models and refuses a used "
          "folder", "[train][own]") {
    const std::string dir = user_folder("own_road");
    const std::string out = testing::temp_dir("own_road_run");
    fs::remove_all(out);
    train::OwnObjectsOptions o;
    o.objects_dir = dir;
    o.out_dir = out;
    o.minutes = 2;
    o.max_steps = 2;  // two steps of each training: the road, not the accuracy
    o.progress = false;
    const train::OwnObjectsSummary s = train::run_own_objects(o);
    CHECK_FALSE(s.interrupted);
    for (const std::string& f : {s.detector, s.pose, out + "/models/models_info.json",
                                 out + "/obj_names.json", out + "/detector.json", out + "/pose.json"})
        CHECK(fs::is_regular_file(f));
    CHECK(s.minutes < 2.0);
    // The pose recipe's warm-up is a share of the run (rot_only_epochs of epochs) and its
    // schedule follows the time.
    const auto pose = nlohmann::json::parse(std::ifstream(out + "/pose.json"));
    CHECK(pose["train"]["time_schedule"] == true);
    CHECK(pose["loss"]["rot_only_epochs"].get<int>() < pose["train"]["epochs"].get<int>());
    CHECK(pose["data"]["object_ids"] == nlohmann::json::array({1, 14}));
    REQUIRE_THROWS_WITH(train::run_own_objects(o), Contains("already holds files") &&
                                                       Contains("--force"));
    o.minutes = 0;
    o.force = true;
    REQUIRE_THROWS_WITH(train::run_own_objects(o), Contains("--minutes must be > 0"));
}
