// Fixture helper built against Debian's libopenvdb-dev (OpenVDB 10): exact compression flags,
// half-float saving and index-to-world maps that pyopenvdb cannot set.
//
//   vdbfix recode IN OUT FLAGS HALF   rewrite every grid of IN with io::File::setCompression(FLAGS)
//                                     (0 none, 1 zip, 2 active mask, 4 blosc, or sums) and
//                                     saveFloatAsHalf(HALF != 0)
//   vdbfix maps OUT                   one small FloatGrid per map type (supported and not)
// OpenVDB's Transform constructor replaces every linear map by its simplest equivalent
// (TranslationMap -> UniformScaleTranslateMap, UnitaryMap -> AffineMap), so files with those
// two map types cannot be written through the public API. This fixture tool opens the class up
// to store them as they are; access specifiers do not change the library's ABI.
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <fstream>
#include <string>
#include <map>
#include <set>
#include <vector>
#include <memory>
#include <mutex>
#include <atomic>
#include <tbb/tbb.h>
#include <Imath/half.h>
#define private public
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/math/Maps.h>
#include <cstdlib>
#include <iostream>
#include <string>

using namespace openvdb;

static int recode(const std::string& in, const std::string& out, uint32_t flags, bool half)
{
    io::File src(in);
    src.open();
    GridPtrVecPtr grids = src.getGrids();
    MetaMap::Ptr meta = src.getMetadata();
    src.close();
    for (auto& g : *grids) g->setSaveFloatAsHalf(half);
    io::File dst(out);
    dst.setCompression(flags);
    dst.write(*grids, *meta);
    dst.close();
    return 0;
}

static FloatGrid::Ptr small(const std::string& name, math::MapBase::Ptr map)
{
    FloatGrid::Ptr g = FloatGrid::create(0.5f);
    g->setName(name);
    math::Transform::Ptr xform(new math::Transform(map));
    xform->mMap = map; // keep the map type as given (see the note at the top)
    g->setTransform(xform);
    auto acc = g->getAccessor();
    acc.setValueOn(Coord(-1, -2, -3), 1.25f);
    acc.setValueOn(Coord(-4, -5, -6), -2.5f);
    return g;
}

static int maps(const std::string& out)
{
    GridPtrVec grids;
    grids.push_back(small("scale", math::MapBase::Ptr(new math::ScaleMap(Vec3d(0.1, 0.2, 0.4)))));
    grids.push_back(small("translation", math::MapBase::Ptr(new math::TranslationMap(Vec3d(1.5, -2.0, 0.25)))));
    grids.push_back(small("uniform_scale", math::MapBase::Ptr(new math::UniformScaleMap(0.03))));
    grids.push_back(small("uniform_scale_translate",
        math::MapBase::Ptr(new math::UniformScaleTranslateMap(0.2, Vec3d(-1.0, 0.5, 2.0)))));
    grids.push_back(small("scale_translate",
        math::MapBase::Ptr(new math::ScaleTranslateMap(Vec3d(0.1, 0.3, 0.2), Vec3d(1.0, 2.0, 3.0)))));
    grids.push_back(small("negative_scale", math::MapBase::Ptr(new math::ScaleMap(Vec3d(0.1, -0.2, 0.4)))));
    math::Mat4d rot = math::Mat4d::identity();
    rot.preRotate(math::Z_AXIS, 0.3);
    rot.preScale(Vec3d(0.1, 0.1, 0.1));
    grids.push_back(small("affine", math::MapBase::Ptr(new math::AffineMap(rot))));
    grids.push_back(small("unitary", math::MapBase::Ptr(new math::UnitaryMap(Vec3d(0, 0, 1), 0.3))));
    FloatGrid::Ptr frustum = small("frustum", math::MapBase::Ptr(new math::UniformScaleMap(1.0)));
    frustum->setTransform(math::Transform::createFrustumTransform(
        BBoxd(Vec3d(0, 0, 0), Vec3d(10, 10, 10)), 0.5, 2.0, 0.1));
    grids.push_back(frustum);
    io::File dst(out);
    dst.write(grids);
    dst.close();
    return 0;
}

int main(int argc, char** argv)
{
    openvdb::initialize();
    std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "recode" && argc == 6) {
        return recode(argv[2], argv[3], uint32_t(std::atoi(argv[4])), std::atoi(argv[5]) != 0);
    }
    if (mode == "maps" && argc == 3) return maps(argv[2]);
    std::cerr << "usage: vdbfix recode IN OUT FLAGS HALF | vdbfix maps OUT\n";
    return 2;
}
