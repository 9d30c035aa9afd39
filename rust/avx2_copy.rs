//! `avx2_copy!`: a function that runs its body in a copy compiled for AVX2 when the CPU has
//! it. Same code, same results: the copy only lets LLVM use 256-bit registers (no fused
//! multiply-add, which would round differently).

/// Defines `fn $name` calling `$body` (an `#[inline(always)]` function taking the same
/// arguments) through `$avx2`, a copy of it compiled with `target_feature(enable = "avx2")`,
/// when [`crate::kernel::use_avx2`] says so. Generic parameters, if any, go in brackets:
///
/// ```ignore
/// avx2_copy! {
///     /// Docs of the public function.
///     pub fn total[T: Sample](values: &[T]) -> f64 => total_avx2, total_body
/// }
/// ```
macro_rules! avx2_copy {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident $([$($generics:tt)*])? ($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?
        => $avx2:ident, $body:ident
    ) => {
        $(#[$attr])*
        $vis fn $name<$($($generics)*)?>($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::kernel::use_avx2() {
                // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
                return unsafe { $avx2($($arg),*) };
            }
            $body($($arg),*)
        }

        #[doc = concat!("[`", stringify!($name), "`] compiled for AVX2.")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        fn $avx2<$($($generics)*)?>($($arg: $ty),*) $(-> $ret)? {
            $body($($arg),*)
        }
    };
}
