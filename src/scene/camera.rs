//! Pinhole and thin-lens camera. `aperture_radius = 0` (the default) is a pinhole.

use crate::geometry::Ray;
use crate::sampling::concentric_disk;
use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
/// A pinhole or thin-lens camera.
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit vector toward the image's right edge.
    pub right: Vec3,
    /// Unit vector toward the image's top edge.
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub vfov_deg: f32,
    /// Radius of the lens aperture in scene units; 0 for a pinhole.
    pub aperture_radius: f32,
    /// Distance to the plane in focus (only used when `aperture_radius > 0`).
    pub focus_distance: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 40.0)
    }
}

impl Camera {
    /// A pinhole camera at `eye` looking at `target`. If `up` is parallel to the view
    /// direction another up vector is chosen.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, vfov_deg: f32) -> Camera {
        let forward = (target - eye).normalize_or(Vec3::NEG_Z);
        let mut right = forward.cross(up);
        if right.length_squared() < 1e-12 {
            right = forward.any_orthonormal_vector();
        }
        let right = right.normalize();
        let up = right.cross(forward);
        Camera {
            position: eye,
            forward,
            right,
            up,
            vfov_deg,
            aperture_radius: 0.0,
            focus_distance: (target - eye).length().max(1e-6),
        }
    }

    /// This camera with a thin lens of `aperture_radius` focused at `focus_distance`.
    pub fn with_lens(mut self, aperture_radius: f32, focus_distance: f32) -> Camera {
        self.aperture_radius = aperture_radius;
        self.focus_distance = focus_distance;
        self
    }

    /// Checks every number (finite, unit axes, field of view in (0, 180), lens values).
    pub fn validate(&self) -> Result<(), String> {
        let finite = self.position.is_finite() && self.forward.is_finite() && self.right.is_finite();
        if !finite {
            return Err("camera position or direction is not finite".into());
        }
        if !(self.vfov_deg > 0.0 && self.vfov_deg < 180.0) {
            return Err(format!("camera fov {} must lie in (0, 180) degrees", self.vfov_deg));
        }
        if !(self.aperture_radius >= 0.0 && self.aperture_radius.is_finite()) {
            return Err("camera aperture radius must be finite and >= 0".into());
        }
        if self.aperture_radius > 0.0 && !(self.focus_distance > 0.0 && self.focus_distance.is_finite()) {
            return Err("camera focus distance must be finite and > 0".into());
        }
        Ok(())
    }

    /// The pinhole projection's constants for a `width × height` image.
    pub fn projection(&self, width: u32, height: u32) -> Projection {
        Projection {
            tan_half: (self.vfov_deg.to_radians() * 0.5).tan(),
            aspect: width as f32 / height as f32,
            width,
            height,
        }
    }

    /// The primary ray through film position `film` (pixels, y down) of a
    /// `width × height` image, with `lens` a uniform sample of `[0,1)²`.
    pub fn generate_ray(&self, film: Vec2, width: u32, height: u32, lens: Vec2) -> Ray {
        self.ray(&self.projection(width, height), film, lens)
    }

    /// [`Camera::generate_ray`] with the projection of the image worked out once (the
    /// same ray, bit for bit).
    #[inline]
    pub fn ray(&self, proj: &Projection, film: Vec2, lens: Vec2) -> Ray {
        let Projection { tan_half, aspect, width, height } = *proj;
        let sx = (2.0 * film.x / width as f32 - 1.0) * tan_half * aspect;
        let sy = (1.0 - 2.0 * film.y / height as f32) * tan_half;
        let dir = (self.forward + self.right * sx + self.up * sy).normalize();
        if self.aperture_radius <= 0.0 {
            return Ray::new(self.position, dir);
        }
        // Thin lens: aim at the point on the focus plane that the pinhole ray reaches.
        let focus = self.position + dir * (self.focus_distance / dir.dot(self.forward));
        let d = concentric_disk(lens) * self.aperture_radius;
        let origin = self.position + self.right * d.x + self.up * d.y;
        Ray::new(origin, (focus - origin).normalize())
    }
}

/// What a pinhole projection of one image size needs besides the camera's frame: the
/// tangent of half the vertical field of view, the image's aspect ratio and its size
/// in pixels. A render works it out once ([`Camera::projection`]) rather than per ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// tan(vfov / 2).
    pub tan_half: f32,
    /// Width over height.
    pub aspect: f32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thin_lens_rays_of_one_pixel_meet_on_the_focus_plane() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 30.0).with_lens(0.3, 4.0);
        let film = Vec2::new(170.0, 40.0);
        let pinhole = Camera { aperture_radius: 0.0, ..cam }.generate_ray(film, 320, 240, Vec2::ZERO);
        let on_plane = |r: Ray| {
            r.at((4.0 - 0.0) / r.dir.dot(cam.forward)
                - (r.origin - cam.position).dot(cam.forward) / r.dir.dot(cam.forward))
        };
        let focus = on_plane(pinhole);
        let mut origins = Vec::new();
        for (i, u) in [Vec2::new(0.1, 0.2), Vec2::new(0.9, 0.5), Vec2::new(0.5, 0.95)].into_iter().enumerate() {
            let r = cam.generate_ray(film, 320, 240, u);
            assert!((on_plane(r) - focus).length() < 1e-4, "lens sample {i}");
            origins.push(r.origin);
        }
        // The lens samples really spread the origins over the aperture.
        assert!((origins[0] - origins[1]).length() > 0.05);
        assert!(origins.iter().all(|o| (*o - cam.position).length() <= 0.3 + 1e-6));
    }
}
