//! A fixed linear congruential generator for the unit tests' random cases (no `rand` crate in
//! the tests): Knuth's MMIX constants, the top 24 bits as a float in [0, 1).

use glam::Vec3A;

pub(crate) struct Lcg(pub u64);

impl Lcg {
    /// A float in [0, 1).
    pub fn f(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A unit vector, uniform on the sphere (rejection from the cube).
    pub fn unit(&mut self) -> Vec3A {
        loop {
            let v = Vec3A::new(self.f(), self.f(), self.f()) * 2.0 - 1.0;
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }
}
