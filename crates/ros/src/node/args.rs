//! `--ros-args` as rcl reads them: `-r __ns:=/cell1`, `-r __node:=NAME`, `-r FROM:=TO`,
//! `-p NAME:=VALUE` and `--params-file FILE`, so `ros2 run` and `ros2 launch` can start
//! `waam node` like any other node.

use std::path::PathBuf;

use super::names::{NodeNames, Remap};

/// What the arguments after `--ros-args` say.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// `-r __ns:=NS`.
    pub namespace: Option<String>,
    /// `-r __node:=NAME` (or `__name`).
    pub node_name: Option<String>,
    /// `-r [NODE:]FROM:=TO`, in order.
    pub remaps: Vec<Remap>,
    /// `-p [NODE:]NAME:=VALUE`, in order: (node, name, YAML value text).
    pub params: Vec<(Option<String>, String, String)>,
    /// `--params-file FILE`, in order.
    pub params_files: Vec<PathBuf>,
    /// Options rcl knows that this node accepts but does not act on (`--log-level`, ...).
    pub ignored: Vec<String>,
}

/// A `--ros-args` argument this node cannot follow; the message names it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("--ros-args: {0}")]
pub struct RosArgsError(pub String);

impl RosArgs {
    /// Parses the arguments that followed `--ros-args` (a further `--ros-args` is allowed;
    /// a closing `--` may end them, with nothing after it: waam's own options go first).
    pub fn parse<S: AsRef<str>>(args: &[S]) -> Result<RosArgs, RosArgsError> {
        let err = |m: String| Err(RosArgsError(m));
        let mut out = RosArgs::default();
        let mut it = args.iter().map(AsRef::as_ref);
        while let Some(arg) = it.next() {
            let mut value = |flag: &str| {
                it.next()
                    .map(str::to_string)
                    .ok_or_else(|| RosArgsError(format!("{flag} needs a value")))
            };
            match arg {
                "--ros-args" => {}
                "--" => {
                    if let Some(next) = it.next() {
                        return err(format!(
                            "{next:?} after `--`: give waam's own options before --ros-args"
                        ));
                    }
                }
                "-r" | "--remap" => {
                    let rule = value(arg)?;
                    let Some((lhs, to)) = rule.split_once(":=") else {
                        return err(format!("remap {rule:?}: expected FROM:=TO"));
                    };
                    let (node, from) = split_node(lhs);
                    if to.is_empty() || from.is_empty() {
                        return err(format!("remap {rule:?}: FROM and TO must not be empty"));
                    }
                    match from {
                        "__ns" => {
                            if !to.starts_with('/') {
                                return err(format!(
                                    "remap {rule:?}: the namespace must be absolute (start with /)"
                                ));
                            }
                            out.namespace = Some(to.trim_end_matches('/').to_string())
                                .filter(|n| !n.is_empty())
                                .or(Some("/".into()));
                        }
                        "__node" | "__name" => out.node_name = Some(to.to_string()),
                        _ => out.remaps.push(Remap {
                            node: node.map(str::to_string),
                            from: from.to_string(),
                            to: to.to_string(),
                        }),
                    }
                }
                "-p" | "--param" => {
                    let rule = value(arg)?;
                    let Some((lhs, v)) = rule.split_once(":=") else {
                        return err(format!("parameter {rule:?}: expected NAME:=VALUE"));
                    };
                    let (node, name) = split_node(lhs);
                    if name.is_empty() {
                        return err(format!("parameter {rule:?}: empty name"));
                    }
                    out.params
                        .push((node.map(str::to_string), name.to_string(), v.to_string()));
                }
                "--params-file" => out.params_files.push(PathBuf::from(value(arg)?)),
                "--log-level" | "--log-config-file" => {
                    let v = value(arg)?;
                    out.ignored.push(format!("{arg} {v}"));
                }
                "--enable-rosout-logs"
                | "--disable-rosout-logs"
                | "--enable-stdout-logs"
                | "--disable-stdout-logs"
                | "--enable-external-lib-logs"
                | "--disable-external-lib-logs" => out.ignored.push(arg.to_string()),
                "-e" | "--enclave" => {
                    return err(format!(
                        "{arg}: security enclaves are not supported by this node"
                    ))
                }
                other => {
                    return err(format!(
                        "unknown argument {other:?} (this node takes -r, -p, --params-file)"
                    ))
                }
            }
        }
        if let Some(ns) = &out.namespace {
            ros2_client::NodeName::new(ns, "n")
                .map_err(|e| RosArgsError(format!("namespace {ns:?} is not valid: {e:?}")))?;
        }
        if let Some(name) = &out.node_name {
            ros2_client::NodeName::new("/", name)
                .map_err(|e| RosArgsError(format!("node name {name:?} is not valid: {e:?}")))?;
        }
        Ok(out)
    }

    /// The node's names after these arguments.
    pub fn names(&self) -> NodeNames {
        let default = NodeNames::default();
        NodeNames {
            namespace: self.namespace.clone().unwrap_or(default.namespace),
            name: self.node_name.clone().unwrap_or(default.name),
            remaps: self.remaps.clone(),
        }
    }
}

/// `node:rest` → (Some(node), rest); a name without a node prefix → (None, name).
fn split_node(lhs: &str) -> (Option<&str>, &str) {
    match lhs.split_once(':') {
        Some((node, rest)) => (Some(node), rest),
        None => (None, lhs),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rcl_forms_are_understood() {
        let a = RosArgs::parse(&[
            "-r",
            "__ns:=/cell1",
            "--remap",
            "__node:=planner",
            "-r",
            "~/status:=/cell1/state",
            "-r",
            "planner:arc_on:=arc",
            "-p",
            "planner.timeout_s:=5.0",
            "--param",
            "planner:mesh.block_mm:=[6, 6, 2]",
            "--params-file",
            "cell.yaml",
            "--log-level",
            "debug",
            "--",
        ])
        .unwrap();
        assert_eq!(a.namespace.as_deref(), Some("/cell1"));
        assert_eq!(a.node_name.as_deref(), Some("planner"));
        assert_eq!(a.remaps.len(), 2);
        assert_eq!(a.remaps[1].node.as_deref(), Some("planner"));
        assert_eq!(
            a.params[1],
            (
                Some("planner".into()),
                "mesh.block_mm".into(),
                "[6, 6, 2]".into()
            )
        );
        assert_eq!(a.params_files, vec![PathBuf::from("cell.yaml")]);
        assert_eq!(a.ignored, vec!["--log-level debug".to_string()]);
        assert_eq!(a.names().fully_qualified(), "/cell1/planner");
        let root = RosArgs::parse(&["-r", "__ns:=/"]).unwrap();
        assert_eq!(root.names().fully_qualified(), "/waam_planner");
    }

    #[test]
    fn bad_arguments_are_named() {
        let e = |args: &[&str]| RosArgs::parse(args).unwrap_err().to_string();
        assert!(e(&["-r", "__ns:=cell1"]).contains("absolute"));
        assert!(e(&["-r", "a=b"]).contains("FROM:=TO"));
        assert!(e(&["-p"]).contains("-p needs a value"));
        assert!(e(&["-p", "x"]).contains("NAME:=VALUE"));
        assert!(e(&["--bogus"]).contains("\"--bogus\""));
        assert!(e(&["--", "--dry-run"]).contains("before --ros-args"));
        assert!(e(&["-r", "__node:=9lives"]).contains("node name"));
    }
}
