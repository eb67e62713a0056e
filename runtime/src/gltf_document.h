// Internal: checks of a glTF file's container and JSON document made before tinygltf 2.7 reads
// them.
//
// tinygltf's own messages name no place ("Invalid glTF binary.", "'componentType' property is
// missing in Accessor.", "primitive indices accessor out of bounds"), and some damage crashes it
// (JSON nested thousands deep, a BIN chunk up to 8 bytes too long). These checks find what tinygltf
// would refuse, and those crashes, first, and return the first problem as a bb::Error naming the
// file, the place (a byte offset in a .glb, a line and column in a .gltf's text, or a JSON path)
// and the reason. What they let through, tinygltf reads.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "bb/result.h"

namespace bb::runtime::detail {

// Where a .glb's chunks lie, in bytes from the start of the file.
struct GlbLayout {
  std::size_t json_at = 0;  // the JSON chunk's payload
  std::size_t json_length = 0;
  bool has_bin = false;        // a BIN chunk follows the JSON chunk
  std::size_t bin_length = 0;  // its payload's length
};

// The .glb container as tinygltf 2.7 reads it: the 12-byte header (magic "glTF", version 2, a
// length of at least 20 bytes and at most the file's), a non-empty JSON chunk first, within that
// length, and after it either nothing or a BIN chunk (4 bytes or more, a multiple of 4) that ends
// within that length too.
Result<GlbLayout> check_glb_container(const unsigned char* bytes, std::size_t size,
                                      const std::string& path);

// JSON nested deeper than this is refused (tinygltf walks extras and extensions recursively).
inline constexpr int kMaxJsonDepth = 256;

// The JSON document of a .gltf (`glb` null; places in the text are lines and columns) or of a
// .glb's JSON chunk (places are bytes from the start of the file): its syntax, numbers within a
// double's range, nesting, the root and `asset` objects, the top-level arrays (of objects), every
// property tinygltf requires (of the JSON type it reads: integers written without a fraction), the
// index each reference holds (within its array), and each buffer's data: a .gltf's buffer needs a
// uri, a data: URI in base64 or a file beside `path` of byteLength bytes; a .glb's buffer without a
// uri takes the BIN chunk, which must be as long.
Status check_gltf_json(std::string_view text, const std::string& path, const GlbLayout* glb);

}  // namespace bb::runtime::detail
