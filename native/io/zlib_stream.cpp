#include "io/zlib_stream.hpp"

#include <libdeflate.h>

#include <memory>
#include <new>
#include <stdexcept>
#include <string>

#include "core/mesh.hpp"

namespace atlas::zlib_stream {
namespace {

struct FreeCompressor {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};
struct FreeDecompressor {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// Compressors hold their level's tables: one per call, as calls come from
// several threads and a page's pixels dwarf the allocation.
std::unique_ptr<libdeflate_compressor, FreeCompressor> compressor(int level) {
  if (level < 0 || level > 12) throw InputError("zlib level must be 0..12, got " + std::to_string(level));
  std::unique_ptr<libdeflate_compressor, FreeCompressor> c(libdeflate_alloc_compressor(level));
  if (!c) throw std::bad_alloc();
  return c;
}

}  // namespace

std::size_t bound(std::size_t size) {
  // libdeflate's bound for a NULL compressor holds for every level.
  return libdeflate_zlib_compress_bound(nullptr, size);
}

std::size_t compress(const std::uint8_t* data, std::size_t size, int level, std::uint8_t* out) {
  const std::size_t written = libdeflate_zlib_compress(compressor(level).get(), data, size, out, bound(size));
  if (written == 0) throw std::logic_error("libdeflate found its own bound too small");
  return written;
}

void inflate(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out, std::size_t out_size) {
  std::unique_ptr<libdeflate_decompressor, FreeDecompressor> d(libdeflate_alloc_decompressor());
  if (!d) throw std::bad_alloc();
  switch (libdeflate_zlib_decompress(d.get(), in, in_size, out, out_size, nullptr)) {
    case LIBDEFLATE_SUCCESS:
      return;
    case LIBDEFLATE_SHORT_OUTPUT:
      throw InputError("zlib stream holds fewer bytes than " + std::to_string(out_size));
    case LIBDEFLATE_INSUFFICIENT_SPACE:
      throw InputError("zlib stream holds more bytes than " + std::to_string(out_size));
    default:
      throw InputError("zlib stream is broken");
  }
}

}  // namespace atlas::zlib_stream
