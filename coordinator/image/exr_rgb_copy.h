// An EXR file's R, G and B without its other channels, copied a band of rows at a time:
// what a client that did not ask for the AOV layers is sent of a stored render, without
// the whole image in memory (coordinator/api/grpc_client_service.cpp, FetchImage).
#pragma once

#include <filesystem>

namespace aliquot {

// Writes `to` with the R, G, B channels and the "namespace:name" string attributes of
// the EXR at `from`: the same bytes write_exr gives for the image read_exr would return
// without its extra channels. Holds one band of rows, not the image. Throws
// ImageFileError (exr_io.h); a half-written `to` is removed.
void copy_exr_rgb(const std::filesystem::path& from, const std::filesystem::path& to);

}  // namespace aliquot
