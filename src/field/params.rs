//! The flat parameter layout: every trainable value of the model lives in one `Vec<f32>` (and its
//! gradient in another of the same length), split into named groups. AdamW applies each group's
//! learning-rate scale; checkpoints store one tensor per group under its name and shape.

use serde::{Deserialize, Serialize};

/// One named slice of the flat buffer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamGroup {
    /// `hash_grid`, `sdf_mlp`, `color_mlp`, `variance`, `appearance`, and with a learned
    /// background (`crate::render::background`) `bg_density` and `bg_color`.
    pub name: String,
    /// First element in the flat buffer.
    pub offset: usize,
    /// Number of elements.
    pub len: usize,
    /// Logical shape (row-major), e.g. `[n_entries, F]` for the hash table,
    /// `[n_codes, code_dim]` for the appearance table, `[len]` for MLPs (layer layout in
    /// [`crate::field::mlp`]).
    pub shape: Vec<usize>,
    /// Multiplies the optimiser's base learning rate (instant-nsr-pl `neus-dtu-wmask.yaml`:
    /// geometry and texture 0.01, variance 0.001 → scales 1 and 0.1 of a base 1e-2).
    pub lr_scale: f32,
}

impl ParamGroup {
    pub fn range(&self) -> std::ops::Range<usize> {
        self.offset..self.offset + self.len
    }
}

/// All groups, contiguous and in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ParamLayout {
    pub groups: Vec<ParamGroup>,
}

impl ParamLayout {
    /// Appends a group after the last one and returns its offset.
    pub fn push(&mut self, name: &str, shape: Vec<usize>, lr_scale: f32) -> usize {
        let offset = self.total();
        let len = shape.iter().product();
        self.groups.push(ParamGroup {
            name: name.to_string(),
            offset,
            len,
            shape,
            lr_scale,
        });
        offset
    }

    /// Total number of parameters.
    pub fn total(&self) -> usize {
        self.groups.last().map_or(0, |g| g.offset + g.len)
    }

    /// The group called `name`, if any.
    pub fn group(&self, name: &str) -> Option<&ParamGroup> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// The group that holds flat index `i`.
    pub fn group_of(&self, i: usize) -> Option<&ParamGroup> {
        self.groups.iter().find(|g| g.range().contains(&i))
    }
}
