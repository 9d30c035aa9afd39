//! Per-thread reuse of registration's large working buffers: frames as float64 planes and
//! their masks, spectra and correlation surfaces.
//!
//! A fresh multi-megabyte buffer costs the kernel a page fault per 4 KiB page on first
//! touch, and the allocator hands freed buffers of that size back to the kernel; at
//! 640×512 that was about a sixth of a translation's time. A [`Buffer`] goes back to its
//! thread's store when dropped, and the next buffer of that element type and a size that
//! fits is taken from there: registering the frames of a sequence, the candidates of a
//! rotation search or a benchmark's repeats touches the same few pages again.
//!
//! Each thread keeps at most [`SPARE_BYTES`] per element type; a buffer that would exceed
//! it is freed as usual. New storage is reserved fallibly ([`crate::budget`]): a refusal
//! unwinds to the operation's guard and becomes its error.

use std::cell::RefCell;
use std::ops::{Deref, DerefMut};

use super::fft::C32;
use crate::budget;

/// Bytes of spare buffers a thread keeps per element type.
pub const SPARE_BYTES: usize = 16 << 20;

/// An element type with a per-thread store of spare buffers.
pub trait Reusable: Copy + Default + 'static {
    /// Run `f` on this thread's store (None while the thread is exiting and the store is gone).
    fn with_spare<R>(f: impl FnOnce(&mut Vec<Vec<Self>>) -> R) -> Option<R>;
}

macro_rules! reusable {
    ($($t:ty),*) => {$(
        impl Reusable for $t {
            fn with_spare<R>(f: impl FnOnce(&mut Vec<Vec<Self>>) -> R) -> Option<R> {
                thread_local! {
                    static SPARE: RefCell<Vec<Vec<$t>>> = const { RefCell::new(Vec::new()) };
                }
                SPARE.try_with(|s| f(&mut s.borrow_mut())).ok()
            }
        }
    )*};
}

reusable!(f64, f32, bool, C32);

/// A `Vec` whose storage returns to the thread's store when dropped.
#[derive(Debug, PartialEq)]
pub struct Buffer<T: Reusable>(Vec<T>);

fn bytes<T>(v: &Vec<T>) -> usize {
    v.capacity() * std::mem::size_of::<T>()
}

/// The smallest spare vector with room for `len` elements (its old contents kept).
fn spare_with_capacity<T: Reusable>(len: usize) -> Option<Vec<T>> {
    T::with_spare(|spare| {
        let fits = spare.iter().enumerate().filter(|(_, b)| b.capacity() >= len);
        let (i, _) = fits.min_by_key(|(_, b)| b.capacity())?;
        Some(spare.swap_remove(i))
    })
    .flatten()
}

/// An empty vector with room for `len` elements: the smallest spare that fits, or new.
fn empty_with_capacity<T: Reusable>(len: usize) -> Vec<T> {
    match spare_with_capacity(len) {
        Some(mut v) => {
            v.clear();
            v
        }
        None => budget::with_capacity(len),
    }
}

impl<T: Reusable> Buffer<T> {
    /// `len` copies of `value`.
    pub fn filled(len: usize, value: T) -> Buffer<T> {
        let mut v = empty_with_capacity(len);
        v.resize(len, value);
        Buffer(v)
    }

    /// `len` elements of unspecified (but initialised) value, for a caller that writes every
    /// one of them: reused storage is not cleared first.
    pub fn scratch(len: usize) -> Buffer<T> {
        let mut v = spare_with_capacity(len).unwrap_or_else(|| budget::with_capacity(len));
        v.truncate(len);
        v.resize(len, T::default());
        Buffer(v)
    }

    /// The `len` elements `iter` yields, written straight into reused storage.
    pub fn collect_exact(len: usize, iter: impl Iterator<Item = T>) -> Buffer<T> {
        let mut v = empty_with_capacity(len);
        v.extend(iter);
        debug_assert_eq!(v.len(), len);
        Buffer(v)
    }
}

impl<T: Reusable> From<Vec<T>> for Buffer<T> {
    fn from(v: Vec<T>) -> Buffer<T> {
        Buffer(v)
    }
}

impl<T: Reusable> Clone for Buffer<T> {
    fn clone(&self) -> Buffer<T> {
        Buffer::collect_exact(self.len(), self.iter().copied())
    }
}

impl<T: Reusable> Deref for Buffer<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.0
    }
}

impl<T: Reusable> DerefMut for Buffer<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.0
    }
}

impl<'a, T: Reusable> IntoIterator for &'a Buffer<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<'a, T: Reusable> IntoIterator for &'a mut Buffer<T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter_mut()
    }
}

impl<T: Reusable> Drop for Buffer<T> {
    fn drop(&mut self) {
        let v = std::mem::take(&mut self.0);
        if bytes(&v) == 0 {
            return;
        }
        T::with_spare(|spare| {
            if spare.iter().map(bytes).sum::<usize>() + bytes(&v) <= SPARE_BYTES {
                spare.push(v);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn storage_is_reused_and_contents_are_fresh() {
        let first = Buffer::filled(1000, 7.0f64);
        let at = first.as_ptr();
        drop(first);
        let second = Buffer::filled(800, 0.0f64);
        assert_eq!(second.as_ptr(), at, "the spare storage is taken again");
        assert!(second.iter().all(|&v| v == 0.0) && second.len() == 800);
        let third = Buffer::collect_exact(3, [1.0, 2.0, 3.0].into_iter());
        assert_ne!(third.as_ptr(), at);
        assert_eq!(&third[..], &[1.0, 2.0, 3.0]);
        assert_eq!(third.clone(), third);
        drop(second);
        let fourth: Buffer<f64> = Buffer::scratch(900);
        assert_eq!(fourth.as_ptr(), at, "scratch storage is reused too");
        assert_eq!(fourth.len(), 900);
    }

    #[test]
    fn storage_the_system_refuses_is_the_operations_error() {
        let err = crate::budget::guard("registration", crate::Error::Registration, || {
            Ok(Buffer::<f64>::filled(usize::MAX / 16, 0.0).len())
        })
        .unwrap_err();
        assert!(matches!(&err, crate::Error::Registration(m) if m.contains("out of memory")), "{err:?}");
        let err = crate::budget::guard("x", crate::Error::Value, || Ok(Buffer::<f32>::scratch(usize::MAX / 8).len()));
        assert!(err.is_err());
    }

    #[test]
    fn the_store_keeps_at_most_its_budget() {
        let big = SPARE_BYTES / std::mem::size_of::<f32>();
        let (a, b) = (Buffer::filled(big, 0.0f32), Buffer::filled(big, 0.0f32));
        drop(a);
        drop(b);
        let kept = f32::with_spare(|s| s.iter().map(bytes).sum::<usize>()).unwrap();
        assert!(kept <= SPARE_BYTES, "{kept}");
    }
}
