//! Parts and a model for the tests of several modules.

use waam_part::graph::WeldGraph;
use waam_part::Part;

use crate::ThermalModel;

pub(crate) fn model(text: &str) -> (Part, ThermalModel) {
    let part = Part::parse(text).unwrap();
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    (part, model)
}

pub(crate) const WALL: &str =
    "name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 2\nlayers: ['####', '####']\n";
