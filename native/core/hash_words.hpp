// Repeated keys found by hashing their exact bit patterns: one pass through an
// open-addressing table instead of a sort (coinciding edges, repeated faces).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace atlas {

// A 64-bit hash of words[0 .. n): each word is folded in with a multiply and a
// shift, then the whole is finalized as splitmix64 finalizes, so that every
// bit of every word reaches the low bits that pick a slot (a word's high bits
// reach them only through a later multiply). Equal keys hash equally; nothing
// else is promised.
inline std::uint64_t hash_words(const std::uint64_t* words, std::size_t n) {
  std::uint64_t h = 0x9e3779b97f4a7c15ull;
  for (std::size_t i = 0; i < n; ++i) {
    h = (h ^ words[i]) * 0xbf58476d1ce4e5b9ull;
    h ^= h >> 31;
  }
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  return h ^ (h >> 31);
}

// first[i] = the smallest j with key(j) == key(i), for i in [0, n): key(i)
// returns a std::array<std::uint64_t, N>, compared word for word. Expected
// O(n) time, 3n ints of memory.
template <class Key>
std::vector<int> first_of_equal_keys(int n, Key key) {
  std::size_t slots = 16;
  while (slots < 2 * static_cast<std::size_t>(n)) slots *= 2;
  std::vector<int> table(slots, -1), first(n);
  for (int i = 0; i < n; ++i) {
    const auto k = key(i);
    std::size_t slot = hash_words(k.data(), k.size()) & (slots - 1);
    while (table[slot] >= 0 && key(table[slot]) != k) slot = (slot + 1) & (slots - 1);
    if (table[slot] < 0) table[slot] = i;
    first[i] = table[slot];
  }
  return first;
}

}  // namespace atlas
