// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cstdint>
#include <string>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/mesh_io.h"
#include "testing.h"

using namespace g2l::geom;
using g2l::geom::test::put;
using g2l::geom::test::write_file;
using Catch::Contains;

namespace {

/// ASCII PLY: 4 vertices with double coords, normals, RGBA colour and an unknown property; one
/// quad and one triangle; an extra `edge` element after the faces.
const char* kAsciiPly =
    "ply\n"
    "format ascii 1.0\n"
    "comment hand-made\n"
    "element vertex 4\n"
    "property double x\nproperty double y\nproperty double z\n"
    "property float nx\nproperty float ny\nproperty float nz\n"
    "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
    "property float quality\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "element edge 1\n"
    "property int vertex1\nproperty int vertex2\n"
    "end_header\n"
    "0 0 0 0 0 1 255 0 0 255 0.5\n"
    "10 0 0 0 0 1 0 255 0 255 0.5\n"
    "10 20 0 0 0 1 0 0 255 255 0.5\n"
    "0 20 -5.5 0 0 1 1 2 3 255 0.5\n"
    "4 0 1 2 3\n"
    "3 3 2 1\n"
    "0 1\n";

/// Binary LE PLY with an int16 property between the coordinates, a uint index list written as
/// `vertex_index`, and an extra uchar per face before the list.
std::string binary_ply() {
    std::string s =
        "ply\r\nformat binary_little_endian 1.0\r\n"
        "element vertex 3\r\n"
        "property float x\r\nproperty short flags\r\nproperty float y\r\nproperty float z\r\n"
        "element face 1\r\n"
        "property uchar tag\r\n"
        "property list uchar uint vertex_index\r\n"
        "end_header\r\n";
    const float v[3][3] = {{1.5f, 2.f, 3.f}, {-4.f, 5.f, 6.25f}, {7.f, -8.f, 9.f}};
    for (const auto& p : v) {
        put<float>(s, p[0]);
        put<int16_t>(s, -7);
        put<float>(s, p[1]);
        put<float>(s, p[2]);
    }
    put<uint8_t>(s, 42);
    put<uint8_t>(s, 3);
    put<uint32_t>(s, 2);
    put<uint32_t>(s, 0);
    put<uint32_t>(s, 1);
    return s;
}

}  // namespace

TEST_CASE("load_ply reads an ASCII PLY with normals, colours, quads and extra elements",
          "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("mesh_ascii");
    write_file(dir + "/m.ply", kAsciiPly);
    const Mesh m = load_mesh(dir + "/m.ply");
    REQUIRE(m.vertices.rows() == 4);
    CHECK(m.vertices(1, 0) == 10.f);
    CHECK(m.vertices(3, 2) == -5.5f);
    REQUIRE(m.normals.rows() == 4);
    CHECK(m.normals(2, 2) == 1.f);
    REQUIRE(m.colors.rows() == 4);
    CHECK(int(m.colors(0, 0)) == 255);
    CHECK(int(m.colors(2, 2)) == 255);
    CHECK(int(m.colors(3, 1)) == 2);
    REQUIRE(m.faces.rows() == 3);  // quad -> 2 triangles, + 1 triangle
    CHECK(m.faces.row(0) == Eigen::RowVector3i(0, 1, 2));
    CHECK(m.faces.row(1) == Eigen::RowVector3i(0, 2, 3));
    CHECK(m.faces.row(2) == Eigen::RowVector3i(3, 2, 1));
    CHECK(m.path == dir + "/m.ply");
}

TEST_CASE("load_ply reads binary little-endian PLY, skipping unknown properties by size",
          "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("mesh_bin");
    write_file(dir + "/b.PLY", binary_ply());
    const Mesh m = load_mesh(dir + "/b.PLY");
    REQUIRE(m.vertices.rows() == 3);
    CHECK(m.vertices.row(0) == Eigen::RowVector3f(1.5f, 2.f, 3.f));
    CHECK(m.vertices.row(1) == Eigen::RowVector3f(-4.f, 5.f, 6.25f));
    CHECK(m.vertices.row(2) == Eigen::RowVector3f(7.f, -8.f, 9.f));
    CHECK(m.normals.rows() == 0);
    CHECK(m.colors.rows() == 0);
    REQUIRE(m.faces.rows() == 1);
    CHECK(m.faces.row(0) == Eigen::RowVector3i(2, 0, 1));
}

TEST_CASE("save_ply then load_ply round-trips vertices, normals, colours and faces exactly",
          "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("mesh_rt");
    write_file(dir + "/m.ply", kAsciiPly);
    const Mesh a = load_ply(dir + "/m.ply");
    save_ply(dir + "/out.ply", a);
    const Mesh b = load_ply(dir + "/out.ply");
    CHECK(b.vertices == a.vertices);
    CHECK(b.normals == a.normals);
    CHECK(b.colors == a.colors);
    CHECK(b.faces == a.faces);
    Mesh bad = a;
    bad.faces(1, 2) = 9;
    REQUIRE_THROWS_WITH(save_ply(dir + "/bad.ply", bad), Contains("face 1 index 9"));
    bad = a;
    bad.normals.conservativeResize(2, 3);
    REQUIRE_THROWS_WITH(save_ply(dir + "/bad.ply", bad), Contains("2 normals for 4 vertices"));
    REQUIRE_THROWS_WITH(save_ply(dir + "/no_such_dir/x.ply", a), Contains("no_such_dir/x.ply"));
}

TEST_CASE("load_obj reads v/f records with slash forms, negative indices and polygons",
          "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("mesh_obj");
    write_file(dir + "/m.obj",
               "# comment\nmtllib x.mtl\no thing\n"
               "v 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0 0.5 0.5 0.5\n"
               "vn 0 0 1\nvt 0 0\ns off\n"
               "f 1/1/1 2/2/1 3/3/1 4/4/1\n"
               "f -1//1 -2//1 -3//1\n"
               "v 0 0 2.5\n"
               "f 5 1/1 2\n");
    const Mesh m = load_mesh(dir + "/m.obj");
    REQUIRE(m.vertices.rows() == 5);
    CHECK(m.vertices(4, 2) == 2.5f);
    REQUIRE(m.faces.rows() == 4);
    CHECK(m.faces.row(0) == Eigen::RowVector3i(0, 1, 2));
    CHECK(m.faces.row(1) == Eigen::RowVector3i(0, 2, 3));
    CHECK(m.faces.row(2) == Eigen::RowVector3i(3, 2, 1));
    CHECK(m.faces.row(3) == Eigen::RowVector3i(4, 0, 1));
}

TEST_CASE("mesh readers reject bad files naming the file and the problem", "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("mesh_bad");
    REQUIRE_THROWS_WITH(load_mesh(dir + "/missing.ply"),
                        Contains("missing.ply") && Contains("cannot open"));
    REQUIRE_THROWS_WITH(load_mesh(dir + "/model.stl"), Contains("'.stl'"));

    // Truncated binary body.
    std::string b = binary_ply();
    write_file(dir + "/trunc.ply", b.substr(0, b.size() - 5));
    REQUIRE_THROWS_WITH(load_ply(dir + "/trunc.ply"),
                        Contains("trunc.ply") && Contains("truncated") && Contains("face 0"));
    // Truncated ASCII body (last vertex row and faces missing).
    std::string a = kAsciiPly;
    write_file(dir + "/trunc_a.ply", a.substr(0, a.find("0 20 -5.5")));
    REQUIRE_THROWS_WITH(load_ply(dir + "/trunc_a.ply"),
                        Contains("truncated") && Contains("vertex 3"));
    // Absurd element count.
    std::string big = a;
    big.replace(big.find("element vertex 4"), 16, "element vertex 4000000000");
    write_file(dir + "/big.ply", big);
    REQUIRE_THROWS_WITH(load_ply(dir + "/big.ply"),
                        Contains("big.ply' declares 4000000000 vertex entries"));
    // No end_header.
    write_file(dir + "/hdr.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
    REQUIRE_THROWS_WITH(load_ply(dir + "/hdr.ply"), Contains("hdr.ply") && Contains("end_header"));
    // Not a PLY.
    write_file(dir + "/notply.ply", "solid x\n");
    REQUIRE_THROWS_WITH(load_ply(dir + "/notply.ply"), Contains("not a PLY"));
    // Big endian.
    std::string be = b;
    be.replace(be.find("binary_little_endian"), 20, "binary_big_endian");
    write_file(dir + "/be.ply", be);
    REQUIRE_THROWS_WITH(load_ply(dir + "/be.ply"), Contains("big_endian") && Contains("be.ply"));
    // Face index out of range.
    std::string oor = a;
    oor.replace(oor.find("3 3 2 1"), 7, "3 3 2 7");
    write_file(dir + "/oor.ply", oor);
    REQUIRE_THROWS_WITH(load_ply(dir + "/oor.ply"),
                        Contains("face 1 index 7 out of range (4 vertices)"));
    // Malformed ASCII number.
    std::string mal = a;
    mal.replace(mal.find("10 20 0"), 2, "1x");
    write_file(dir + "/mal.ply", mal);
    REQUIRE_THROWS_WITH(load_ply(dir + "/mal.ply"), Contains("malformed number '1x'"));
    // Unknown property type.
    std::string ty = a;
    ty.replace(ty.find("property float quality"), 22, "property quad quality");
    write_file(dir + "/ty.ply", ty);
    REQUIRE_THROWS_WITH(load_ply(dir + "/ty.ply"), Contains("unknown property type 'quad'"));
    // Missing z.
    write_file(dir + "/noz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                 "property float y\nend_header\n1 2\n");
    REQUIRE_THROWS_WITH(load_ply(dir + "/noz.ply"), Contains("x, y and z"));
    // Degenerate face.
    std::string two = a;
    two.replace(two.find("3 3 2 1"), 7, "2 3 2");
    write_file(dir + "/two.ply", two);
    REQUIRE_THROWS_WITH(load_ply(dir + "/two.ply"), Contains("face 1 has 2 corners"));
    // OBJ errors.
    write_file(dir + "/a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    REQUIRE_THROWS_WITH(load_obj(dir + "/a.obj"),
                        Contains("a.obj' line 4") && Contains("face index 4 out of range"));
    write_file(dir + "/b.obj", "v 0 0 zero\n");
    REQUIRE_THROWS_WITH(load_obj(dir + "/b.obj"), Contains("line 1") && Contains("'zero'"));
    write_file(dir + "/c.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
    REQUIRE_THROWS_WITH(load_obj(dir + "/c.obj"), Contains("line 3: face has 2 corners"));
    write_file(dir + "/d.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    REQUIRE_THROWS_WITH(load_obj(dir + "/d.obj"), Contains("face index 0 out of range"));
}

TEST_CASE("load_ply reads the real YCB-V (binary) and LM-O (ASCII) models", "[geometry]") {
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) {
        g2l::testing::skip_without_shared_data("real PLY models");
        return;
    }
    const Mesh y = load_mesh(*shared + "/ycbv/models/obj_000001.ply");
    CHECK(y.vertices.rows() == 7678);
    CHECK(y.faces.rows() == 15728);
    CHECK(y.normals.rows() == 0);
    CHECK(y.colors.rows() == 0);
    CHECK(y.faces.minCoeff() >= 0);
    CHECK(y.faces.maxCoeff() < 7678);
    // Extent matches models_info.json (min_x -52.592, size_z 140.144).
    CHECK(y.vertices.col(0).minCoeff() == Approx(-52.592).margin(0.01));
    CHECK(y.vertices.col(2).maxCoeff() - y.vertices.col(2).minCoeff() ==
          Approx(140.144).margin(0.01));

    const Mesh l = load_mesh(*shared + "/lmo/models/obj_000001.ply");
    REQUIRE(l.vertices.rows() == 5841);
    CHECK(l.faces.rows() == 11678);
    REQUIRE(l.normals.rows() == 5841);
    REQUIRE(l.colors.rows() == 5841);
    // First vertex line: -23.0565 17.4191 -6.756 -0.617876 0.77406 -0.138061 148 57 57 255
    CHECK(l.vertices.row(0) == Eigen::RowVector3f(-23.0565f, 17.4191f, -6.756f));
    CHECK(l.normals(0, 1) == Approx(0.77406f));
    CHECK(int(l.colors(0, 0)) == 148);
    CHECK(int(l.colors(0, 2)) == 57);
    CHECK(int(l.colors(2, 0)) == 151);
}
