//! The prepared scene on the device: the triangle acceleration structures ([`SceneAccel`],
//! Morton-ordered bottom levels per mesh) and the core's [`SceneTables`] (meshes,
//! triangles with their normals and materials, the emitters for next-event estimation),
//! together descriptor set 0 of the camera and photon passes: binding 0 the top level,
//! 1 the scene info (uniform), 2 meshes, 3 triangles, 4 emitters, 5 texture words
//! (read-only storage), as
//! the core's `path/scene.wgsl` and `scene_trace.wgsl` declare them.

use crate::accel::SceneAccel;
use crate::buffer::Buffer;
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, Resource};
use arpa_core::gpu::scene::SceneTables;
use arpa_core::render::prepared_scene::PreparedScene;
use ash::vk;

/// The kinds of descriptor set 0 of a pass that traces the scene.
pub const SCENE_SET: [BindingKind; 6] = [
    BindingKind::AccelerationStructure,
    BindingKind::UniformBuffer,
    BindingKind::StorageBuffer,
    BindingKind::StorageBuffer,
    BindingKind::StorageBuffer,
    BindingKind::StorageBuffer,
];

/// The scene's structures and tables on the device (see the module documentation).
pub struct VkScene {
    accel: SceneAccel,
    info: Buffer,
    meshes: Buffer,
    triangles: Buffer,
    emitters: Buffer,
    texture_words: Buffer,
}

impl VkScene {
    /// Builds the acceleration structures of `scene` and uploads its tables.
    ///
    /// Errors: [`VkError::InvalidInput`] for a scene the tables cannot index; device errors.
    pub fn upload(ctx: &VkContext, scene: &PreparedScene) -> Result<Self, VkError> {
        let accel = SceneAccel::build(ctx, scene)?;
        let tables = SceneTables::new(scene, accel.triangle_orders())
            .map_err(|e| VkError::InvalidInput { what: "scene".into(), reason: e.to_string() })?;
        // A binding must hold at least one record: empty tables get one zeroed record.
        fn at_least_one<T: Default + Clone>(mut v: Vec<T>) -> Vec<T> {
            if v.is_empty() {
                v.push(T::default());
            }
            v
        }
        // SAFETY: a physical device of this instance.
        let max_range = u64::from(unsafe { ctx.instance().get_physical_device_properties(ctx.physical_device()) }.limits.max_storage_buffer_range);
        let texture_bytes = 4 * tables.texture_words.len() as u64;
        if texture_bytes > max_range {
            return Err(VkError::InvalidInput {
                what: "scene textures".into(),
                reason: format!("{texture_bytes} bytes of texels and texture coordinates exceed the device's maxStorageBufferRange {max_range}"),
            });
        }
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(Self {
            info: ctx.upload("scene info", bytemuck::bytes_of(&tables.info), vk::BufferUsageFlags::UNIFORM_BUFFER)?,
            meshes: ctx.upload("scene meshes", bytemuck::cast_slice(&at_least_one(tables.meshes)), storage)?,
            triangles: ctx.upload("scene triangles", bytemuck::cast_slice(&at_least_one(tables.triangles)), storage)?,
            emitters: ctx.upload("scene emitters", bytemuck::cast_slice(&at_least_one(tables.emitters)), storage)?,
            texture_words: ctx.upload("scene textures", bytemuck::cast_slice(&tables.texture_words), storage)?,
            accel,
        })
    }

    /// The acceleration structures.
    pub fn accel(&self) -> &SceneAccel {
        &self.accel
    }

    /// Descriptor set 0 of a pass that traces the scene ([`SCENE_SET`]'s kinds).
    pub fn resources(&self) -> [Resource<'_>; 6] {
        [
            Resource::AccelerationStructure(self.accel.tlas()),
            Resource::UniformBuffer(&self.info),
            Resource::StorageBuffer(&self.meshes),
            Resource::StorageBuffer(&self.triangles),
            Resource::StorageBuffer(&self.emitters),
            Resource::StorageBuffer(&self.texture_words),
        ]
    }
}
