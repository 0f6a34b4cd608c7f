//! Errors and warnings of the scene-file loader. Every error names the file (and, for the
//! XML scene description, the line) and the problem; the loader never panics.

use std::path::PathBuf;

/// Why a scene file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneFileError {
    /// A file (scene or mesh) could not be read.
    #[error("cannot read '{}': {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The XML is not well formed.
    #[error("{}:{line}: malformed XML: {message}", path.display())]
    Xml {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// What the XML parser reported.
        message: String,
    },
    /// An element, plugin type or parameter value that the loader does not support.
    #[error("{}:{line}: unsupported {element}: {message}", path.display())]
    Unsupported {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the element.
        line: usize,
        /// The element, e.g. `<shape type="disk">`.
        element: String,
        /// Why, and what is supported instead.
        message: String,
    },
    /// A well-formed but invalid scene description (bad number, missing attribute,
    /// unknown reference, degenerate transform, ...).
    #[error("{}:{line}: {message}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the element.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// `$name` is used but neither a `<default>` nor a `-D name=value` defines it.
    #[error("{}:{line}: undefined parameter '${name}' (define it with <default name=\"{name}\" value=\"...\"/> or -D {name}=VALUE)", path.display())]
    UndefinedVariable {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the element using it.
        line: usize,
        /// The parameter name.
        name: String,
    },
    /// A `-D` argument that is not `name=value`.
    #[error("invalid parameter definition '{0}': expected NAME=VALUE")]
    BadDefine(String),
    /// A PLY mesh file is malformed, truncated or uses an unsupported layout.
    #[error("PLY file '{}': {message}", path.display())]
    Ply {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A Wavefront OBJ mesh file is malformed.
    #[error("OBJ file '{}': {message}", path.display())]
    Obj {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A texture's image file cannot be decoded or is not a supported format.
    #[error("texture file '{}': {message}", path.display())]
    Texture {
        /// The image file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A Mitsuba serialized mesh file is malformed, truncated or has no shape `shape_index`.
    #[error("serialized mesh file '{}': {message}", path.display())]
    Serialized {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A glTF file (or one of its buffers or images) is malformed, refers to data it does
    /// not hold, or requires an extension the loader does not support.
    #[error("glTF file '{}': {message}", path.display())]
    Gltf {
        /// The glTF file (or the buffer or image file named in the message).
        path: PathBuf,
        /// What is wrong, naming the accessor, image, material or node.
        message: String,
    },
    /// A mesh's data is unusable (non-finite vertex, index out of range, ...).
    #[error("mesh '{mesh}' ({}:{line}): {message}", path.display())]
    Mesh {
        /// The scene file.
        path: PathBuf,
        /// Line of the `<shape>` element.
        line: usize,
        /// Mesh file name or shape type.
        mesh: String,
        /// What is wrong.
        message: String,
    },
    /// The loaded scene fails [`arpa_core::render::scene::Scene::validate`].
    #[error("scene '{}' is invalid: {source}", path.display())]
    Scene {
        /// The scene file.
        path: PathBuf,
        /// The validation error.
        source: arpa_core::render::scene::SceneError,
    },
}

/// Something the loader approximated or ignored; the scene still loads.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// The scene file.
    pub path: PathBuf,
    /// 1-based line of the element concerned.
    pub line: usize,
    /// What was approximated or ignored.
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.path.display(), self.line, self.message)
    }
}
