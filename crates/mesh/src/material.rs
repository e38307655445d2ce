//! Materials and textures a mesh file named, carried unchanged so that a writer can give
//! them back.
//!
//! The mesh never reads them: the file formats fill and write them (coarsen-io keeps a
//! glTF document's materials, textures, samplers and images here, and an OBJ file's
//! `mtllib` materials). Which material a face uses is the face label column
//! [`MATERIAL`], carried like every face column.

/// The name of the face label column that says which material each face uses (an index
/// into the materials of [`Materials::json`]).
pub const MATERIAL: &str = "material";

/// Materials, textures and images of a file, kept to be written back unchanged.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Materials {
    /// A glTF 2.0 JSON object with the arrays `materials`, `textures`, `samplers` and
    /// `images` as the file gave them (every image's data in [`Materials::images`]
    /// instead, at the same index); empty when the file named no material.
    pub json: String,
    /// The images, at the indices of the `images` array of [`Materials::json`].
    pub images: Vec<Image>,
}

impl Materials {
    /// True when no material is carried.
    pub fn is_empty(&self) -> bool {
        self.json.is_empty()
    }
}

/// One texture image: where the file pointed to it and, when it could be read, its bytes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Image {
    /// The URI the file gave (a relative path), if the image was not embedded.
    pub uri: Option<String>,
    /// Its MIME type (`image/png`, `image/jpeg`), if known.
    pub mime_type: Option<String>,
    /// The image file's bytes, when embedded or read beside the mesh file.
    pub bytes: Option<Vec<u8>>,
}
