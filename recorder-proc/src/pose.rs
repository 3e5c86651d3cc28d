//! A robot's orientation for the viewer: the telemetry's Unity-convention Euler angles
//! (SPEC S2) turned back into the quaternion the sim derived them from.

/// The unit quaternion `[x, y, z, w]` of Unity Euler angles `[θx, θy, θz]` (radians):
/// `q = Ry(θy) · Rx(θx) · Rz(θz)`, the inverse of the sim's `unity_euler`.
pub fn unity_quaternion(euler: [f64; 3]) -> [f32; 4] {
    let [x, y, z] = euler;
    let about = |axis: usize, angle: f64| {
        let mut q = [0.0, 0.0, 0.0, (0.5 * angle).cos()];
        q[axis] = (0.5 * angle).sin();
        q
    };
    let q = mul(mul(about(1, y), about(0, x)), about(2, z));
    q.map(|v| v as f32)
}

/// The Hamilton product `a · b` of quaternions `[x, y, z, w]`.
fn mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rotates `v` by the unit quaternion `q`.
    fn rotate(q: [f32; 4], v: [f64; 3]) -> [f64; 3] {
        let q = q.map(f64::from);
        let p = [v[0], v[1], v[2], 0.0];
        let conj = [-q[0], -q[1], -q[2], q[3]];
        let r = mul(mul(q, p), conj);
        [r[0], r[1], r[2]]
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
    }

    #[test]
    fn single_angles_turn_about_their_axes() {
        let h = std::f64::consts::FRAC_PI_2;
        // Yaw a quarter turn: forward (+Z) turns to +X.
        assert!(close(
            rotate(unity_quaternion([0.0, h, 0.0]), [0.0, 0.0, 1.0]),
            [1.0, 0.0, 0.0]
        ));
        // Pitch a quarter turn about the axle (X): forward turns to -Y.
        assert!(close(
            rotate(unity_quaternion([h, 0.0, 0.0]), [0.0, 0.0, 1.0]),
            [0.0, -1.0, 0.0]
        ));
        // Roll a quarter turn about forward (Z): +X turns to +Y.
        assert!(close(
            rotate(unity_quaternion([0.0, 0.0, h]), [1.0, 0.0, 0.0]),
            [0.0, 1.0, 0.0]
        ));
    }

    #[test]
    fn angles_compose_roll_first_then_pitch_then_yaw() {
        let e = [0.3, -1.1, 0.2];
        let v = [0.4, -0.5, 0.9];
        let stepwise = rotate(
            unity_quaternion([0.0, e[1], 0.0]),
            rotate(
                unity_quaternion([e[0], 0.0, 0.0]),
                rotate(unity_quaternion([0.0, 0.0, e[2]]), v),
            ),
        );
        assert!(close(rotate(unity_quaternion(e), v), stepwise));
        let norm: f32 = unity_quaternion(e).iter().map(|c| c * c).sum();
        assert!((norm - 1.0).abs() < 1e-6);
    }
}
