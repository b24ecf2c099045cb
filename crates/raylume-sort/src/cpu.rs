//! The CPU reference sort that the GPU sort is tested against.

/// Stable sort of `(key, value)` pairs by the low `key_bits` bits of the key (1..=32; values
/// above 32 are treated as 32). Keys keep their upper bits; only the order uses the low ones.
///
/// Panics if `keys` and `values` differ in length (a programming error in a test).
pub fn sort_pairs_cpu(keys: &[u32], values: &[u32], key_bits: u32) -> (Vec<u32>, Vec<u32>) {
    assert_eq!(
        keys.len(),
        values.len(),
        "sort_pairs_cpu: keys and values differ in length"
    );
    let mask = key_mask(key_bits);
    let mut pairs: Vec<(u32, u32)> = keys.iter().copied().zip(values.iter().copied()).collect();
    pairs.sort_by_key(|&(k, _)| k & mask);
    pairs.into_iter().unzip()
}

/// The mask of the low `key_bits` bits (all ones from 32 on).
pub const fn key_mask(key_bits: u32) -> u32 {
    if key_bits >= 32 {
        u32::MAX
    } else {
        (1u32 << key_bits) - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sorts_by_masked_key_stably() {
        let keys = [5, 0x8000_0003, 3, 1, 0x4000_0003];
        let vals = [0, 1, 2, 3, 4];
        let (k, v) = sort_pairs_cpu(&keys, &vals, 30);
        // 0x8000_0003 and 0x4000_0003 equal 3 in the low 30 bits: original order kept.
        assert_eq!(k, vec![1, 0x8000_0003, 3, 0x4000_0003, 5]);
        assert_eq!(v, vec![3, 1, 2, 4, 0]);
        let (k, _) = sort_pairs_cpu(&keys, &vals, 32);
        assert_eq!(k, vec![1, 3, 5, 0x4000_0003, 0x8000_0003]);
        assert_eq!(key_mask(0), 0);
        assert_eq!(key_mask(8), 0xFF);
    }
}
