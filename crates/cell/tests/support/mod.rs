//! What the cell's tests share: the first plan, found as every caller finds it.

use waam_part::Part;

/// The pipeline's best plan of `part` (fragments of block indices).
pub fn first_plan(part: &Part) -> Vec<Vec<usize>> {
    let outcome = waam_pipeline::plan(part, None, &Default::default(), &mut |_| {}).unwrap();
    outcome
        .report
        .best
        .expect("the test part has a plan")
        .fragments
}
