//! A forward-mode dual number with a fixed tangent width, `Copy` and allocation-free: the
//! hinge's Hessian is the derivative of its closed-form gradient in 12 directions, where a
//! plain array tangent is several times faster than a general AD type (benches/elements.rs).

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic the hinge gradient needs, for f64 and for dual numbers.
pub(crate) trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Mul<f64, Output = Self>
{
    fn sqrt(self) -> Self;
    fn recip(self) -> Self;
}

/// a - b, a . b and a x b on 3-arrays of any number type with + - x: f64, `Dual`, and
/// num-dual's types (the hinge's angle, its closed-form gradient and the Gaussian term's).
#[inline]
pub(crate) fn sub3<T: Copy + Sub<Output = T>>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub(crate) fn dot3<T: Copy + Add<Output = T> + Mul<Output = T>>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub(crate) fn cross3<T: Copy + Sub<Output = T> + Mul<Output = T>>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

impl Real for f64 {
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn recip(self) -> Self {
        1.0 / self
    }
}

/// value + sum_i eps_i d_i
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    pub re: f64,
    pub eps: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// The i-th independent variable with value `re`.
    #[inline]
    pub(crate) fn variable(re: f64, i: usize) -> Self {
        let mut eps = [0.0; N];
        eps[i] = 1.0;
        Dual { re, eps }
    }
    #[inline]
    fn chain(self, re: f64, d: f64) -> Self {
        Dual { re, eps: self.eps.map(|e| e * d) }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Dual { re: self.re + o.re, eps: std::array::from_fn(|i| self.eps[i] + o.eps[i]) }
    }
}
impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Dual { re: self.re - o.re, eps: std::array::from_fn(|i| self.eps[i] - o.eps[i]) }
    }
}
#[allow(clippy::suspicious_arithmetic_impl)] // the product rule
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        Dual { re: self.re * o.re, eps: std::array::from_fn(|i| self.eps[i] * o.re + o.eps[i] * self.re) }
    }
}
#[allow(clippy::suspicious_arithmetic_impl)] // a / b = a (1 / b)
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        self * o.recip()
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Dual { re: -self.re, eps: self.eps.map(|e| -e) }
    }
}
impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, k: f64) -> Self {
        Dual { re: self.re * k, eps: self.eps.map(|e| e * k) }
    }
}
impl<const N: usize> Real for Dual<N> {
    #[inline]
    fn sqrt(self) -> Self {
        let r = self.re.sqrt();
        self.chain(r, 0.5 / r)
    }
    #[inline]
    fn recip(self) -> Self {
        let r = 1.0 / self.re;
        self.chain(r, -r * r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_of_a_composite() {
        // f(x, y) = sqrt(x y) / (x - y) at (3, 2)
        let (x, y) = (Dual::<2>::variable(3.0, 0), Dual::<2>::variable(2.0, 1));
        let f = (x * y).sqrt() / (x - y);
        let s = 6f64.sqrt();
        assert!((f.re - s).abs() < 1e-14);
        // df/dx = y / (2 s (x - y)) - s / (x - y)^2 ; df/dy = x / (2 s (x - y)) + s / (x - y)^2
        assert!((f.eps[0] - (2.0 / (2.0 * s) - s)).abs() < 1e-12);
        assert!((f.eps[1] - (3.0 / (2.0 * s) + s)).abs() < 1e-12);
    }
}
