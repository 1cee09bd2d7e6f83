// Writes the fuzzers' seed corpora with the project's own writers: kd-tree cache files of
// the fuzz mesh (SAH and thesis, with their mode bytes), tiny images in every format
// load_image reads, scene files (scene_to_json and a short hand-written one), and gzip
// PLY seeds: each hand-written PLY seed compressed, and small gzip bombs. Run from the
// repository root after building the `fuzz` preset:
//   build/fuzz/tests/fuzz_seeds tests/fuzz/corpus        all corpora
//   build/fuzz/tests/fuzz_seeds tests/fuzz/corpus ply    the gzip PLY seeds only
// The plain PLY seeds are hand-written and not regenerated here. Cache seeds have no .kdt
// extension, which .gitignore reserves for real cache files.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <zlib.h>

#include "renderer/accel/kdtree_cache.h"
#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/scene/scene.h"
#include "tests/fuzz/fuzz_inputs.h"
#include "tests/test_util.h"

namespace {

namespace fs = std::filesystem;
using kdt::test::read_bytes;
using kdt::test::write_bytes;

// A cache seed: the mode byte, then a file written by save_kdtree.
void cache_seed(const fs::path& dir, const std::string& name, uint8_t mode) {
    const kdt::KdTreeParams params = kdt::fuzz::cache_params(mode);
    auto tree = kdt::build_kdtree(kdt::fuzz::cache_mesh(), params);
    const fs::path tmp = dir / (name + ".tmp");
    kdt::save_kdtree(tmp.string(), *tree);
    std::vector<unsigned char> bytes = read_bytes(tmp);
    fs::remove(tmp);
    bytes.insert(bytes.begin(), mode);
    write_bytes(dir / name, bytes);
}

kdt::ImageRGB gradient(int w, int h) {
    kdt::ImageRGB image(w, h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            image.set(x, y,
                      kdt::Vec3f(float(x) / float(w), float(y) / float(h), 0.25f * float(x + y)));
        }
    }
    return image;
}

// A scene with every kind of material, a file and a builtin mesh and an environment map.
kdt::Scene seed_scene() {
    kdt::Scene scene;
    scene.name = "seed";
    for (size_t i = 0; i < kdt::kMaterialTypeNames.size(); ++i) {
        kdt::MeshInstance m;
        m.file = i % 2 ? "builtin:icosphere" : "meshes/part.ply";
        m.material.type = kdt::MaterialType(i);
        m.material.emission = kdt::Vec3f(float(i));
        m.world_from_object[3] = kdt::Vec4f(float(i), 0.0f, 0.0f, 1.0f);
        m.smooth = i % 2 == 0;
        scene.meshes.push_back(m);
    }
    scene.environment.file = "sky.hdr";
    scene.environment.mapping = kdt::EnvMapping::angular;
    scene.environment.rotation_degrees = 30.0f;
    return scene;
}

void write_text(const fs::path& p, const std::string& text) {
    write_bytes(p, std::vector<unsigned char>(text.begin(), text.end()));
}

// `text` as one gzip member, at deflate's best compression.
std::string gzip_member(const std::string& text) {
    z_stream zs{};
    if (deflateInit2(&zs, 9, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY) != Z_OK)
        throw kdt::Error("fuzz_seeds: deflateInit2 failed");
    std::string out(deflateBound(&zs, uLong(text.size())) + 64, '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
    zs.avail_in = uInt(text.size());
    zs.next_out = reinterpret_cast<Bytef*>(out.data());
    zs.avail_out = uInt(out.size());
    const int status = deflate(&zs, Z_FINISH);
    deflateEnd(&zs);
    if (status != Z_STREAM_END) throw kdt::Error("fuzz_seeds: deflate failed");
    out.resize(zs.total_out);
    return out;
}

// gzip PLY seeds in dir: every plain .ply seed there compressed, one split over two gzip
// members, and small bombs (a MiB run of one byte is a member of about 1 KiB): a huge
// count over zeros, trailing newlines, data that ends far short of the header's count.
void ply_gz_seeds(const fs::path& dir) {
    std::vector<fs::path> plain;
    for (const auto& entry : fs::directory_iterator(dir))
        if (entry.path().extension() == ".ply") plain.push_back(entry.path());
    std::sort(plain.begin(), plain.end());
    for (const fs::path& p : plain) {
        const std::vector<unsigned char> bytes = read_bytes(p);
        write_text(fs::path(p.string() + ".gz"),
                   gzip_member(std::string(bytes.begin(), bytes.end())));
    }
    const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
    const std::string face = "property list uchar int vertex_indices\n";
    const std::string tri = "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "element face 1\n" +
                            face + "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    write_text(dir / "two_members.ply.gz", gzip_member(tri.substr(0, tri.size() / 2)) +
                                               gzip_member(tri.substr(tri.size() / 2)));
    const std::string mib_zeros = gzip_member(std::string(size_t(1) << 20, '\0'));
    const std::string mib_newlines = gzip_member(std::string(size_t(1) << 20, '\n'));
    std::string bomb =
        gzip_member("ply\nformat binary_little_endian 1.0\nelement vertex 300000000\n" + xyz +
                    "element face 1000\n" + face + "end_header\n");
    std::string trailing = gzip_member(tri);
    // 1 MiB each, small enough to keep the fuzzer's rate up; the newlines outlast the
    // reader's look for trailing data.
    bomb += mib_zeros;
    trailing += mib_newlines;
    write_text(dir / "bomb_count.ply.gz", bomb);
    write_text(dir / "trailing_newlines.ply.gz", trailing);
    std::string short_data =
        "ply\nformat ascii 1.0\nelement vertex 100000\n" + xyz + "end_header\n";
    for (int k = 0; k < 10; ++k) short_data += std::to_string(k) + " 0.5 -1\n";
    write_text(dir / "short_data.ply.gz", gzip_member(short_data));
}

}  // namespace

int main(int argc, char** argv) {
    const bool ply_only = argc == 3 && std::string(argv[2]) == "ply";
    if (argc != 2 && !ply_only) {
        std::fprintf(stderr, "usage: fuzz_seeds <corpus directory> [ply]\n");
        return 2;
    }
    try {
        const fs::path root = argv[1];
        ply_gz_seeds(root / "ply");
        if (ply_only) return 0;
        const fs::path cache = root / "cache", image = root / "image", scene = root / "scene";
        fs::create_directories(cache);
        fs::create_directories(image);
        fs::create_directories(scene);
        cache_seed(cache, "sah_resealed", 1);
        cache_seed(cache, "sah_raw", 0);
        cache_seed(cache, "thesis_resealed", 5);

        kdt::write_hdr((image / "flat.hdr").string(), gradient(5, 3));
        kdt::write_hdr((image / "rle.hdr").string(), gradient(9, 2));
        kdt::write_pfm((image / "colour.pfm").string(), gradient(3, 2));
        kdt::write_png((image / "text.png").string(), gradient(4, 3), {},
                       {{"kdtrace.spp", "16"}, {"Comment", "gr\xc3\xbcn"}});
        kdt::write_exr((image / "float_zip.exr").string(), gradient(4, 3),
                       {{"kdtrace.scene", "fuzz"}});
        // Half, uint, grey and other compressions: tests/fuzz/exr_seeds.cpp (OpenEXR).
        // Grey PFM, big-endian (positive scale): written by hand, our writer makes "PF" only.
        std::string pf = "Pf\n2 2\n1.0\n";
        std::vector<unsigned char> grey(pf.begin(), pf.end());
        for (unsigned char b : {0x3f, 0x80, 0, 0, 0x3f, 0, 0, 0, 0x3e, 0x80, 0, 0, 0, 0, 0, 0})
            grey.push_back(b);
        write_bytes(image / "grey_be.pfm", grey);

        write_text(scene / "written.json", kdt::scene_to_json(seed_scene()));
        write_text(scene / "short.json",
                   "{\"name\": \"s\", \"meshes\": [{\"file\": \"m.ply\", \"transform\": "
                   "{\"translate\": [1, 2, 3], \"rotate\": [0, 90, 0], \"scale\": 2}, "
                   "\"material\": {\"type\": \"dielectric\", \"ior\": 1.33}}, "
                   "{\"file\": \"m.ply\", \"smooth\": false}],\n"
                   " \"environment\": {\"color\": 0.5, \"intensity\": 2}}\n");
    } catch (const kdt::Error& e) {
        std::fprintf(stderr, "fuzz_seeds: %s\n", e.what());
        return 1;
    }
    return 0;
}
