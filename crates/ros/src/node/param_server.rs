//! The six `rcl_interfaces` parameter services (what `ros2 param list/get/set/describe/dump`
//! call), answered from the node's [`NodeParams`] and the [`declared`] table, so each
//! parameter is described with its type, range and description, and a set is checked
//! against the same rules as the parameters file before it is applied.
//!
//! `ros2-client`'s own parameter services describe nothing and check values one at a time,
//! so the node turns them off and serves these instead.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces::*;
use ros2_client::{Message, Name, Node, ParameterValue, QosProfile, Server, ServiceMapping};
use ros2_client::{Parameter, ServiceTypeName};

use super::declared::{self, ParamError, DECLARED, USE_SIM_TIME};
use super::params::{NodeParams, ParamRule};
use super::pipeline::SetupError;
use super::ros::ServeError;

/// Checks a changed set of parameters beyond their ranges (can the process file be read?)
/// and, when it returns `Ok`, puts them to use from the next plan.
pub type OnChange = dyn Fn(&NodeParams) -> Result<(), ChangeError> + Send + Sync;

/// Why new parameters were not put to use.
#[derive(Debug, thiserror::Error)]
pub enum ChangeError {
    /// The pipeline cannot be built from them (a process file that cannot be read, ...).
    #[error(transparent)]
    Setup(#[from] SetupError),
    #[error("the node is shutting down")]
    ShuttingDown,
}

/// Why a set of parameter changes was refused (all of them: a set is applied whole).
#[derive(Debug, thiserror::Error)]
pub enum SetError {
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error(transparent)]
    Range(#[from] ParamRule),
    #[error(transparent)]
    Change(#[from] ChangeError),
}

/// The node's parameters, shared by the services and whoever reads them.
pub struct ParamStore {
    params: Mutex<NodeParams>,
    on_change: Box<OnChange>,
}

impl ParamStore {
    pub fn new(params: NodeParams, on_change: Box<OnChange>) -> Arc<ParamStore> {
        Arc::new(ParamStore {
            params: Mutex::new(params),
            on_change,
        })
    }

    pub fn current(&self) -> NodeParams {
        self.params
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    fn names() -> impl Iterator<Item = &'static str> {
        std::iter::once(USE_SIM_TIME).chain(DECLARED.iter().map(|d| d.name))
    }

    pub fn get(&self, name: &str) -> ParameterValue {
        if name == USE_SIM_TIME {
            return ParameterValue::Boolean(false);
        }
        match declared::find(name) {
            Some(d) => d.get(&self.params.lock().unwrap_or_else(|e| e.into_inner())),
            None => ParameterValue::NotSet,
        }
    }

    /// Applies all of `changes` or none; the error says which one is wrong and why.
    pub fn set_all(&self, changes: &[(String, ParameterValue)]) -> Result<(), SetError> {
        let mut guard = self.params.lock().unwrap_or_else(|e| e.into_inner());
        let mut next = guard.clone();
        for (name, value) in changes {
            declared::set(&mut next, name, value, true)?;
        }
        next.check()?;
        if next != *guard {
            (self.on_change)(&next)?;
            *guard = next;
        }
        Ok(())
    }

    fn describe(&self, name: &str) -> raw::ParameterDescriptor {
        let params = self.current();
        let mut d = match declared::find(name) {
            Some(d) => d.descriptor(&params),
            None if name == USE_SIM_TIME => {
                let mut d = ros2_client::parameters::ParameterDescriptor::from_value(
                    name,
                    &ParameterValue::Boolean(false),
                );
                d.description =
                    "Use /clock: not supported, the node runs on wall-clock time".into();
                d.additional_constraints = "false only".into();
                d
            }
            None => ros2_client::parameters::ParameterDescriptor::unknown(name),
        };
        d.name = name.to_string();
        d.into()
    }

    /// rclcpp's ListParameters: no prefixes lists names with fewer than `depth` dots (0 =
    /// any); else the names equal to a prefix or under `prefix.` within `depth` levels.
    fn list(&self, prefixes: &[String], depth: u64) -> ListParametersResult {
        let within = |s: &str| depth == 0 || (s.matches('.').count() as u64) < depth;
        let mut result = ListParametersResult {
            names: vec![],
            prefixes: vec![],
        };
        for name in Self::names() {
            let all = prefixes.is_empty() && within(name);
            let under = prefixes.iter().any(|p| {
                name == p
                    || name
                        .strip_prefix(p.as_str())
                        .and_then(|r| r.strip_prefix('.'))
                        .is_some_and(within)
            });
            if all || under {
                result.names.push(name.to_string());
                if let Some((ns, _)) = name.rsplit_once('.') {
                    if !result.prefixes.iter().any(|p| p == ns) {
                        result.prefixes.push(ns.to_string());
                    }
                }
            }
        }
        result
    }
}

/// The six services of node `fqn`, answered on a thread of their own until `stop` is raised.
pub fn serve(
    node: &mut Node,
    fqn: &str,
    store: Arc<ParamStore>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, ServeError> {
    let get = server::<GetParametersRequest, GetParametersResponse>(
        node,
        fqn,
        "get_parameters",
        "GetParameters",
    )?;
    let types = server::<GetParameterTypesRequest, GetParameterTypesResponse>(
        node,
        fqn,
        "get_parameter_types",
        "GetParameterTypes",
    )?;
    let set = server::<SetParametersRequest, SetParametersResponse>(
        node,
        fqn,
        "set_parameters",
        "SetParameters",
    )?;
    let set_atomic = server::<SetParametersRequest, SetParametersAtomicallyResponse>(
        node,
        fqn,
        "set_parameters_atomically",
        "SetParametersAtomically",
    )?;
    let list = server::<ListParametersRequest, ListParametersResponse>(
        node,
        fqn,
        "list_parameters",
        "ListParameters",
    )?;
    let describe = server::<DescribeParametersRequest, DescribeParametersResponse>(
        node,
        fqn,
        "describe_parameters",
        "DescribeParameters",
    )?;
    let changes = |req: &SetParametersRequest| -> Vec<(String, ParameterValue)> {
        req.parameter
            .iter()
            .cloned()
            .map(Parameter::from)
            .map(|p| (p.name, p.value))
            .collect()
    };
    std::thread::Builder::new()
        .name("ros-params".into())
        .spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let mut busy = false;
                if let Some((id, req)) = take(&get) {
                    busy = true;
                    let values = req.names.iter().map(|n| store.get(n).into()).collect();
                    reply(&get, id, GetParametersResponse { values });
                }
                if let Some((id, req)) = take(&types) {
                    busy = true;
                    let values = req
                        .names
                        .iter()
                        .map(|n| ParameterValue::to_parameter_type_raw(&store.get(n)))
                        .collect();
                    reply(&types, id, GetParameterTypesResponse { values });
                }
                if let Some((id, req)) = take(&set) {
                    busy = true;
                    // Each parameter on its own, as rclcpp's SetParameters does.
                    let results = changes(&req)
                        .into_iter()
                        .map(|change| {
                            let result = store.set_all(std::slice::from_ref(&change));
                            log_set(&change.0, &result);
                            // The service's answer: the reason as text.
                            result.map_err(|e| e.to_string()).into()
                        })
                        .collect();
                    reply(&set, id, SetParametersResponse { results });
                }
                if let Some((id, req)) = take(&set_atomic) {
                    busy = true;
                    let result = store.set_all(&changes(&req));
                    log_set("(atomically)", &result);
                    reply(
                        &set_atomic,
                        id,
                        SetParametersAtomicallyResponse {
                            result: result.map_err(|e| e.to_string()).into(),
                        },
                    );
                }
                if let Some((id, req)) = take(&list) {
                    busy = true;
                    let result = store.list(&req.prefixes, req.depth);
                    reply(&list, id, ListParametersResponse { result });
                }
                if let Some((id, req)) = take(&describe) {
                    busy = true;
                    let values = req.names.iter().map(|n| store.describe(n)).collect();
                    reply(&describe, id, DescribeParametersResponse { values });
                }
                if !busy {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        })
        .map_err(|source| ServeError::Thread {
            thread: "the parameter thread".into(),
            source,
        })
}

fn log_set(name: &str, result: &Result<(), SetError>) {
    match result {
        Ok(()) => tracing::info!("parameter {name} set; it applies from the next plan"),
        Err(e) => tracing::warn!("parameter set refused: {e}"),
    }
}

fn server<Req: Message + Clone + 'static, Resp: Message + 'static>(
    node: &mut Node,
    fqn: &str,
    service: &str,
    type_name: &str,
) -> Result<Server<Req, Resp>, ServeError> {
    let name = Name::new(fqn, service).map_err(|e| ServeError::BadName {
        name: format!("{fqn}/{service}"),
        reason: format!("{e:?}"),
    })?;
    let qos =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    node.create_server(
        ServiceMapping::Enhanced,
        &name,
        &ServiceTypeName::new("rcl_interfaces", type_name),
        qos.clone(),
        qos,
    )
    .map_err(|e| ServeError::Create {
        what: "service",
        name: format!("{fqn}/{service}"),
        reason: format!("{e:?}"),
    })
}

fn take<Req: Message + 'static, Resp: Message + 'static>(
    server: &Server<Req, Resp>,
) -> Option<(ros2_client::RmwRequestId, Req)> {
    match server.receive_request() {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!("parameter service request: {e:?}");
            None
        }
    }
}

fn reply<Req: Message + 'static, Resp: Message + 'static>(
    server: &Server<Req, Resp>,
    id: ros2_client::RmwRequestId,
    response: Resp,
) {
    if let Err(e) = server.send_response(id, response) {
        tracing::warn!("parameter service response: {e:?}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_are_checked_whole_and_listed_like_rclcpp() {
        let store = ParamStore::new(NodeParams::default(), Box::new(|_| Ok(())));
        let listed = store.list(&[], 0);
        assert_eq!(listed.names.len(), DECLARED.len() + 1);
        assert!(listed.prefixes.contains(&"planner".to_string()));
        let planner = store.list(&["planner".into()], 1);
        assert_eq!(
            planner.names,
            vec![
                "planner.timeout_s",
                "planner.default_max_fragments",
                "planner.max_memory_mb",
                "planner.threads"
            ]
        );
        let e = store
            .set_all(&[(
                "mesh.block_mm".into(),
                ParameterValue::DoubleArray(vec![1.0, 2.0]),
            )])
            .unwrap_err();
        assert!(e.to_string().contains("mesh.block_mm"), "{e}");
        let e = store
            .set_all(&[("planner.timeout_s".into(), ParameterValue::Double(-1.0))])
            .unwrap_err();
        assert!(e.to_string().contains("planner.timeout_s"), "{e}");
        store
            .set_all(&[("planner.timeout_s".into(), ParameterValue::Double(3.0))])
            .unwrap();
        assert_eq!(store.current().planner.timeout_s, 3.0);
        let d = store.describe("planner.timeout_s");
        assert_eq!(d.r#type, 3);
        assert_eq!(d.floating_point_range.len(), 1);
        assert!(!d.description.is_empty());
        let refused = ParamStore::new(
            NodeParams::default(),
            Box::new(|_| Err(ChangeError::ShuttingDown)),
        );
        assert!(refused
            .set_all(&[("planner.timeout_s".into(), ParameterValue::Double(3.0))])
            .is_err());
        assert_eq!(refused.current().planner.timeout_s, 60.0);
    }
}
