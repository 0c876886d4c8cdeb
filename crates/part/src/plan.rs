//! Plans: the block-sequence format of `shared/spec/plan-format.md` and its validity rules.
//!
//! A plan is an ordered list of fragments, a fragment the ordered list of blocks one weld
//! path deposits between an arc-on and an arc-off.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::graph::WeldGraph;
use crate::{Block, BlockDisplay, Part};

/// A plan as read from (or written to) a file: fragments of block coordinates. A key the
/// format does not have (a misspelt `fragment:`) is an error, not silently ignored.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// The name of the part the plan is for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub part: Option<String>,
    pub fragments: Vec<Vec<Block>>,
    /// For a graph part: the same fragments as node ids, which is what its plan file holds
    /// (docs/graph-part-format.md); the blocks above are then the planning stand-ins.
    #[serde(skip)]
    pub nodes: Option<Vec<Vec<usize>>>,
}

/// A plan file that cannot be read as a plan at all.
#[derive(Debug, Error)]
pub enum PlanReadError {
    #[error("the plan file is not UTF-8 text (first bad byte at offset {0})")]
    NotUtf8(usize),
    #[error("plan is not valid JSON: {0}")]
    Json(String),
    #[error("plan is not valid YAML or not a plan ('part' and a 'fragments' list of [x, y, z] integer triples): {0}")]
    Yaml(String),
}

/// The first validity rule a plan breaks, naming the block and the rule.
#[derive(Debug, Clone, Error, PartialEq, Eq)]
pub enum Invalid {
    #[error("rule 1: {} (fragment {fragment}, position {position}) is not a block of the part", BlockDisplay(*block))]
    UnknownBlock {
        block: Block,
        fragment: usize,
        position: usize,
    },
    #[error("rule 1: block {} appears twice (fragment {fragment}, position {position})", BlockDisplay(*block))]
    Repeated {
        block: Block,
        fragment: usize,
        position: usize,
    },
    #[error("rule 1: block {} does not appear in the plan", BlockDisplay(*block))]
    Missing { block: Block },
    #[error("rule 2: {count} fragments, allowed 1..{max}")]
    FragmentCount { count: usize, max: usize },
    #[error("rule 2: fragment {fragment} is empty")]
    EmptyFragment { fragment: usize },
    #[error("rule 3: fragment {fragment} moves {} -> {} (position {position}), not a weld-graph edge", BlockDisplay(*from), BlockDisplay(*to))]
    NotAnEdge {
        from: Block,
        to: Block,
        fragment: usize,
        position: usize,
    },
    #[error("rule 4: block {} is in fragment {fragment}, the block below it in fragment {below_fragment}", BlockDisplay(*block))]
    Gravity {
        block: Block,
        fragment: usize,
        below_fragment: usize,
    },
}

impl Invalid {
    /// The rule number of plan-format.md (1 to 4).
    pub fn rule(&self) -> u8 {
        match self {
            Invalid::UnknownBlock { .. } | Invalid::Repeated { .. } | Invalid::Missing { .. } => 1,
            Invalid::FragmentCount { .. } | Invalid::EmptyFragment { .. } => 2,
            Invalid::NotAnEdge { .. } => 3,
            Invalid::Gravity { .. } => 4,
        }
    }

    /// The block the broken rule is about, if it names one.
    pub fn block(&self) -> Option<Block> {
        match *self {
            Invalid::UnknownBlock { block, .. }
            | Invalid::Repeated { block, .. }
            | Invalid::Missing { block }
            | Invalid::Gravity { block, .. } => Some(block),
            Invalid::NotAnEdge { to, .. } => Some(to),
            _ => None,
        }
    }
}

impl Plan {
    /// Reads a plan from bytes: JSON when `json` (or when it starts with `{`), else YAML.
    pub fn from_bytes(bytes: &[u8], json: bool) -> Result<Plan, PlanReadError> {
        let text =
            std::str::from_utf8(bytes).map_err(|e| PlanReadError::NotUtf8(e.valid_up_to()))?;
        if json || text.trim_start().starts_with('{') {
            serde_json::from_str(text).map_err(|e| PlanReadError::Json(e.to_string()))
        } else {
            crate::yaml::check(text).map_err(|e| PlanReadError::Yaml(e.to_string()))?;
            serde_yaml::from_str(text).map_err(|e| PlanReadError::Yaml(e.to_string()))
        }
    }

    /// The plan as YAML, one fragment per line.
    pub fn to_yaml(&self) -> String {
        let mut out = String::new();
        if let Some(name) = &self.part {
            let quoted = serde_json::to_string(name).expect("a string serializes");
            let _ = writeln!(out, "part: {quoted}");
        }
        out.push_str("fragments:\n");
        if let Some(nodes) = &self.nodes {
            for fragment in nodes {
                let ids: Vec<String> = fragment.iter().map(usize::to_string).collect();
                let _ = writeln!(out, "  - [{}]", ids.join(", "));
            }
            return out;
        }
        for fragment in &self.fragments {
            let blocks: Vec<String> = fragment
                .iter()
                .map(|b| format!("[{},{},{}]", b[0], b[1], b[2]))
                .collect();
            let _ = writeln!(out, "  - [{}]", blocks.join(", "));
        }
        out
    }

    /// A plan of block indices turned back into coordinates.
    pub fn from_indices(part: &Part, fragments: &[Vec<usize>]) -> Plan {
        Plan {
            part: Some(part.name.clone()),
            fragments: fragments
                .iter()
                .map(|f| f.iter().map(|&i| part.block(i)).collect())
                .collect(),
            nodes: part.bead_part().map(|_| fragments.to_vec()),
        }
    }

    /// Number of blocks in the plan.
    pub fn len(&self) -> usize {
        self.fragments.iter().map(Vec::len).sum()
    }

    /// True for a plan of no blocks.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks the four validity rules in order and returns the plan as block indices.
    pub fn validate(&self, part: &Part, graph: &WeldGraph) -> Result<Vec<Vec<usize>>, Invalid> {
        const UNSEEN: usize = usize::MAX;
        // fragment_of[i]: the (0-based) fragment block i is welded in.
        let mut fragment_of = vec![UNSEEN; part.len()];
        let mut indexed = Vec::with_capacity(self.fragments.len());
        for (f, fragment) in self.fragments.iter().enumerate() {
            let mut ids = Vec::with_capacity(fragment.len());
            for (p, &block) in fragment.iter().enumerate() {
                let (fragment, position) = (f + 1, p + 1);
                let i = part.index_of(block).ok_or(Invalid::UnknownBlock {
                    block,
                    fragment,
                    position,
                })?;
                if fragment_of[i] != UNSEEN {
                    return Err(Invalid::Repeated {
                        block,
                        fragment,
                        position,
                    });
                }
                fragment_of[i] = f;
                ids.push(i);
            }
            indexed.push(ids);
        }
        if let Some(i) = fragment_of.iter().position(|&f| f == UNSEEN) {
            return Err(Invalid::Missing {
                block: part.block(i),
            });
        }
        let count = self.fragments.len();
        if count == 0 || count > part.max_fragments {
            return Err(Invalid::FragmentCount {
                count,
                max: part.max_fragments,
            });
        }
        if let Some(f) = indexed.iter().position(Vec::is_empty) {
            return Err(Invalid::EmptyFragment { fragment: f + 1 });
        }
        for (f, ids) in indexed.iter().enumerate() {
            for (p, pair) in ids.windows(2).enumerate() {
                if !graph.has_edge(pair[0], pair[1]) {
                    return Err(Invalid::NotAnEdge {
                        from: part.block(pair[0]),
                        to: part.block(pair[1]),
                        fragment: f + 1,
                        position: p + 1,
                    });
                }
            }
        }
        for (f, ids) in indexed.iter().enumerate() {
            for &i in ids {
                for &j in graph.supports(i) {
                    if fragment_of[j as usize] > f {
                        return Err(Invalid::Gravity {
                            block: part.block(i),
                            fragment: f + 1,
                            below_fragment: fragment_of[j as usize] + 1,
                        });
                    }
                }
            }
        }
        Ok(indexed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (Part, WeldGraph) {
        // Two layers of a 3-block wall.
        let part =
            Part::parse("name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 2\nlayers: ['###', '###']\n")
                .unwrap();
        let graph = WeldGraph::new(&part);
        (part, graph)
    }

    fn check(fragments: Vec<Vec<Block>>) -> Result<Vec<Vec<usize>>, Invalid> {
        let (part, graph) = setup();
        Plan {
            part: None,
            fragments,
            nodes: None,
        }
        .validate(&part, &graph)
    }

    #[test]
    fn a_valid_plan_passes() {
        let ok = check(vec![
            vec![[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 0, 1]],
            vec![[1, 0, 1], [0, 0, 1]],
        ]);
        assert_eq!(ok.unwrap(), vec![vec![0, 1, 2, 5], vec![4, 3]]);
    }

    #[test]
    fn each_rule_is_reported() {
        let all = |extra: Vec<Block>| {
            let mut f = vec![
                [0, 0, 0],
                [1, 0, 0],
                [2, 0, 0],
                [2, 0, 1],
                [1, 0, 1],
                [0, 0, 1],
            ];
            f.extend(extra);
            f
        };
        let e = check(vec![all(vec![[3, 0, 0]])]).unwrap_err();
        assert_eq!((e.rule(), e.block()), (1, Some([3, 0, 0])));
        let e = check(vec![all(vec![[0, 0, 0]])]).unwrap_err();
        assert!(matches!(e, Invalid::Repeated { position: 7, .. }), "{e}");
        let e = check(vec![vec![[0, 0, 0]]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "rule 1: block [1,0,0] does not appear in the plan"
        );
        let e = check(vec![all(vec![]), vec![], vec![]]).unwrap_err();
        assert_eq!(e.to_string(), "rule 2: 3 fragments, allowed 1..2");
        let e = check(vec![all(vec![]), vec![]]).unwrap_err();
        assert_eq!(e.to_string(), "rule 2: fragment 2 is empty");
        let e = check(vec![vec![
            [0, 0, 0],
            [2, 0, 0],
            [1, 0, 0],
            [1, 0, 1],
            [0, 0, 1],
            [2, 0, 1],
        ]])
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "rule 3: fragment 1 moves [0,0,0] -> [2,0,0] (position 1), not a weld-graph edge"
        );
        let e = check(vec![
            vec![[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
            vec![[2, 0, 0]],
        ]);
        assert!(e.is_err());
        let e = check(vec![
            vec![[0, 0, 0], [0, 0, 1], [1, 0, 1], [2, 0, 1]],
            vec![[1, 0, 0], [2, 0, 0]],
        ])
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "rule 4: block [1,0,1] is in fragment 1, the block below it in fragment 2"
        );
    }

    #[test]
    fn yaml_and_json_read_alike() {
        let y = Plan::from_bytes(b"part: w\nfragments:\n  - [[0,0,0], [1,0,0]]\n", false).unwrap();
        let j =
            Plan::from_bytes(br#"{"part": "w", "fragments": [[[0,0,0],[1,0,0]]]}"#, true).unwrap();
        assert_eq!(y, j);
        assert_eq!(Plan::from_bytes(y.to_yaml().as_bytes(), false).unwrap(), y);
        assert!(Plan::from_bytes(b"fragments: [[[0,0]]]", false).is_err());
        assert!(Plan::from_bytes(b"fragments: [[[0,0,0.5]]]", false).is_err());
    }
}
