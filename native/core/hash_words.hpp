// Hashing of exact bit patterns, for the open-addressing tables that find
// repeated keys (coinciding edges, repeated faces) in one pass instead of a sort.
#pragma once
#include <cstddef>
#include <cstdint>

namespace atlas {

// A 64-bit hash of words[0 .. n): each word is folded in with a multiply and a
// shift (after splitmix64), so keys that differ in any bit spread over the
// table. Equal keys hash equally; nothing else is promised.
inline std::uint64_t hash_words(const std::uint64_t* words, std::size_t n) {
  std::uint64_t h = 0x9e3779b97f4a7c15ull;
  for (std::size_t i = 0; i < n; ++i) {
    h = (h ^ words[i]) * 0xbf58476d1ce4e5b9ull;
    h ^= h >> 31;
  }
  return h;
}

}  // namespace atlas
