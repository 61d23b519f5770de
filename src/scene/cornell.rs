//! The built-in Cornell box: the default scene, needing no files.
//!
//! Room `[-1, 1] × [0, 2] × [-1, 1]` (open toward +z), red left wall, green right wall,
//! two white blocks turned ±17°, and a 0.47 × 0.38 area light just below the ceiling.
//! Reflectances and the light's colour follow the widely used Cornell box data set
//! (white 0.725/0.71/0.68, red 0.63/0.065/0.05, green 0.14/0.45/0.091, Le = 17/12/4).

use super::camera::Camera;
use super::data::Scene;
use super::material::Material;
use glam::{Mat3, Vec3};

struct Builder {
    scene: Scene,
}

impl Builder {
    fn material(&mut self, name: &str, m: Material, emission: Vec3) -> u32 {
        self.scene.add_material(name, m, emission)
    }

    /// A planar quad `a b c d` (in order around its edge) as two triangles whose
    /// winding normal points along `facing`.
    fn quad(&mut self, corners: [Vec3; 4], facing: Vec3, material: u32) {
        let [a, b, c, _] = corners;
        let flip = (b - a).cross(c - a).dot(facing) < 0.0;
        let base = self.scene.positions.len() as u32;
        self.scene.positions.extend_from_slice(&corners);
        let (t0, t1) = if flip { ([0, 2, 1], [0, 3, 2]) } else { ([0, 1, 2], [0, 2, 3]) };
        for t in [t0, t1] {
            self.scene.triangles.push(t.map(|i| base + i));
            self.scene.material_of.push(material);
        }
    }

    /// An upright block standing on the floor: footprint centre `(x, z)`, half extents,
    /// turned by `angle_deg` about +y; four sides and a top, normals outward.
    fn block(&mut self, x: f32, z: f32, half: Vec3, angle_deg: f32, material: u32) {
        let rot = Mat3::from_rotation_y(angle_deg.to_radians());
        let centre = Vec3::new(x, half.y, z);
        let corner = |sx: f32, sy: f32, sz: f32| centre + rot * (half * Vec3::new(sx, sy, sz));
        let faces: [([Vec3; 4], Vec3); 5] = [
            ([corner(-1., 1., -1.), corner(1., 1., -1.), corner(1., 1., 1.), corner(-1., 1., 1.)], Vec3::Y),
            ([corner(-1., -1., 1.), corner(1., -1., 1.), corner(1., 1., 1.), corner(-1., 1., 1.)], rot * Vec3::Z),
            ([corner(-1., -1., -1.), corner(1., -1., -1.), corner(1., 1., -1.), corner(-1., 1., -1.)], rot * -Vec3::Z),
            ([corner(1., -1., -1.), corner(1., -1., 1.), corner(1., 1., 1.), corner(1., 1., -1.)], rot * Vec3::X),
            ([corner(-1., -1., -1.), corner(-1., -1., 1.), corner(-1., 1., 1.), corner(-1., 1., -1.)], rot * -Vec3::X),
        ];
        for (q, n) in faces {
            self.quad(q, n, material);
        }
    }
}

/// The built-in Cornell box: 32 triangles (five walls, two five-sided blocks, one light).
pub fn cornell_box() -> Scene {
    let mut b = Builder { scene: Scene::empty("<built-in cornell box>") };
    let white = b.material("white", Material::Diffuse { albedo: Vec3::new(0.725, 0.71, 0.68) }, Vec3::ZERO);
    let red = b.material("red", Material::Diffuse { albedo: Vec3::new(0.63, 0.065, 0.05) }, Vec3::ZERO);
    let green = b.material("green", Material::Diffuse { albedo: Vec3::new(0.14, 0.45, 0.091) }, Vec3::ZERO);
    let light = b.material("light", Material::Diffuse { albedo: Vec3::splat(0.78) }, Vec3::new(17.0, 12.0, 4.0));
    // The blocks have materials of their own (white too) so scene files can replace them.
    let short = b.material("shortBlock", Material::Diffuse { albedo: Vec3::new(0.725, 0.71, 0.68) }, Vec3::ZERO);
    let tall = b.material("tallBlock", Material::Diffuse { albedo: Vec3::new(0.725, 0.71, 0.68) }, Vec3::ZERO);

    let v = Vec3::new;
    b.quad([v(-1., 0., -1.), v(1., 0., -1.), v(1., 0., 1.), v(-1., 0., 1.)], Vec3::Y, white); // floor
    b.quad([v(-1., 2., -1.), v(1., 2., -1.), v(1., 2., 1.), v(-1., 2., 1.)], -Vec3::Y, white); // ceiling
    b.quad([v(-1., 0., -1.), v(1., 0., -1.), v(1., 2., -1.), v(-1., 2., -1.)], Vec3::Z, white); // back
    b.quad([v(-1., 0., -1.), v(-1., 0., 1.), v(-1., 2., 1.), v(-1., 2., -1.)], Vec3::X, red); // left
    b.quad([v(1., 0., -1.), v(1., 0., 1.), v(1., 2., 1.), v(1., 2., -1.)], -Vec3::X, green); // right
    b.block(0.33, 0.37, Vec3::new(0.3, 0.3, 0.3), -17.0, short);
    b.block(-0.34, -0.29, Vec3::new(0.3, 0.6, 0.3), 17.0, tall);
    b.quad(
        [v(-0.235, 1.98, -0.19), v(0.235, 1.98, -0.19), v(0.235, 1.98, 0.19), v(-0.235, 1.98, 0.19)],
        -Vec3::Y,
        light,
    );

    b.scene.camera = Camera::look_at(v(0.0, 1.0, 3.9), v(0.0, 1.0, 0.0), Vec3::Y, 38.0);
    b.scene
}
