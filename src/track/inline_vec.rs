//! A vector of at most `N` small values stored inline, for per-identity
//! lists of a fixed largest size (an identity's neighbours).
//!
//! The live tracker walks every identity's neighbours every frame. Kept in
//! a `Vec` each, they were a thousand separate heap blocks at 1 000
//! markers, scattered over the heap by the once-a-second refresh that
//! rebuilds them; once the daemon's other work had evicted the caches,
//! every block was fetched from memory on its own. Inline, they lie in the
//! identities' own array, which the frame walks in order, so the processor
//! streams them in.

use std::ops::{Deref, DerefMut};

/// Up to `N` values of `T`, inline; derefs to the slice of those held.
#[derive(Debug, Clone, Copy)]
pub(crate) struct InlineVec<T: Copy + Default, const N: usize> {
    items: [T; N],
    /// How many of `items` are held (the rest are defaults, never read).
    len: u8,
}

impl<T: Copy + Default, const N: usize> InlineVec<T, N> {
    /// An empty list.
    pub(crate) fn new() -> Self {
        const { assert!(N <= u8::MAX as usize) };
        InlineVec {
            items: [T::default(); N],
            len: 0,
        }
    }
}

impl<T: Copy + Default, const N: usize> Default for InlineVec<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy + Default, const N: usize> Deref for InlineVec<T, N> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        &self.items[..usize::from(self.len)]
    }
}

impl<T: Copy + Default, const N: usize> DerefMut for InlineVec<T, N> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.items[..usize::from(self.len)]
    }
}

impl<T: Copy + Default, const N: usize> FromIterator<T> for InlineVec<T, N> {
    /// The first `N` values of `iter`: callers hand at most `N` (the
    /// neighbour search keeps that many), so nothing is ever cut.
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        let mut v = Self::new();
        for (slot, item) in v.items.iter_mut().zip(iter) {
            *slot = item;
            v.len += 1;
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Holds what it was built from, in order, up to its capacity; reads
    /// and writes go to the held values only.
    #[test]
    fn holds_up_to_its_capacity_in_order() {
        let v: InlineVec<u32, 4> = (1..=3).collect();
        assert_eq!(&v[..], &[1, 2, 3]);
        let mut full: InlineVec<u32, 4> = (1..=9).collect();
        assert_eq!(&full[..], &[1, 2, 3, 4]);
        full.iter_mut().for_each(|x| *x *= 10);
        assert_eq!(&full[..], &[10, 20, 30, 40]);
        assert!(InlineVec::<u32, 4>::default().is_empty());
    }
}
