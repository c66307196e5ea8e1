// Whole zlib streams (RFC 1950) in one call, through libdeflate: PNG pixel
// data is compressed and inflated as one buffer of known size, which
// libdeflate does in a fraction of zlib's time (it needs no streaming state
// and sizes nothing on the fly).
#pragma once
#include <cstddef>
#include <cstdint>

namespace atlas::zlib_stream {

// Bytes that compress() may write for `size` input bytes.
std::size_t bound(std::size_t size);

// Compresses data[0, size) at `level` (1 the fastest .. 12 the smallest; 0
// stores the bytes uncompressed) into out, which holds bound(size) bytes.
// Returns the bytes written. Throws InputError on a level outside 0..12.
std::size_t compress(const std::uint8_t* data, std::size_t size, int level, std::uint8_t* out);

// Inflates one zlib stream into exactly out_size bytes at out. Throws
// InputError when the stream is broken (its Adler-32 included) or holds
// more or fewer bytes than out_size.
void inflate(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out, std::size_t out_size);

}  // namespace atlas::zlib_stream
