//! Playing a recording back to ROS 2 topics (`waam replay BAG --publish`): every recorded
//! topic gets a publisher of its type offering its recorded QoS, and the messages go out in
//! receive-time order with their original spacing (scaled by a rate).

use std::collections::BTreeMap;
use std::net::{IpAddr, Ipv4Addr};
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::{Context, Name, Node, NodeName, NodeOptions, QosProfile};

use waam_rosbag::Bag;
use waam_rosmsg::dispatch::{visit_type, TypeVisitor};
use waam_rosmsg::{from_cdr, AnyMessage};

/// Playback could not start or a message could not be sent.
#[derive(Debug, thiserror::Error)]
pub enum PublishError {
    #[error("ROS_DOMAIN_ID={0:?} is not a domain id (an integer 0..=232)")]
    DomainId(String),
    #[error("cannot start ROS 2 (DDS): {0}")]
    Dds(String),
    #[error("topic {topic}: {reason}")]
    Topic { topic: String, reason: String },
}

/// Where to publish: the domain id and discovery range rcl would use, from `ROS_DOMAIN_ID`,
/// `ROS_AUTOMATIC_DISCOVERY_RANGE` (LOCALHOST / OFF: loopback only) and `ROS_LOCALHOST_ONLY`.
pub fn context_from_env() -> Result<Context, PublishError> {
    let var = |k: &str| std::env::var(k).ok().filter(|v| !v.trim().is_empty());
    let domain = match var("ROS_DOMAIN_ID") {
        None => 0,
        Some(text) => match text.trim().parse::<u16>() {
            Ok(id) if id <= 232 => id,
            _ => return Err(PublishError::DomainId(text)),
        },
    };
    let range = var("ROS_AUTOMATIC_DISCOVERY_RANGE").map(|r| r.trim().to_ascii_uppercase());
    let localhost = matches!(range.as_deref(), Some("LOCALHOST") | Some("OFF"))
        || var("ROS_LOCALHOST_ONLY").as_deref().map(str::trim) == Some("1");
    let mut builder = DomainParticipantBuilder::new(domain);
    if localhost {
        builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
    }
    let participant = builder
        .build()
        .map_err(|e| PublishError::Dds(e.to_string()))?;
    Context::from_domain_participant(participant).map_err(|e| PublishError::Dds(e.to_string()))
}

/// A topic that cannot be created, published or read (the DDS layer's words).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct TopicError(pub String);

impl From<String> for TopicError {
    fn from(message: String) -> Self {
        TopicError(message)
    }
}

impl From<&str> for TopicError {
    fn from(message: &str) -> Self {
        TopicError(message.to_string())
    }
}

/// Sends one recorded message (CDR) on its topic.
type SendFn = Box<dyn Fn(&[u8]) -> Result<(), TopicError>>;

/// Creates a typed publisher for one topic; its closure decodes recorded CDR and sends it.
struct MakePublisher<'a> {
    node: &'a mut Node,
    name: &'a Name,
    qos: QosProfile,
}

impl TypeVisitor for MakePublisher<'_> {
    type Output = Result<SendFn, TopicError>;

    fn visit<M>(self) -> Result<SendFn, TopicError>
    where
        M: AnyMessage,
    {
        let topic = self
            .node
            .create_topic(self.name, M::message_type_name(), &self.qos)
            .map_err(|e| e.to_string())?;
        let publisher = self
            .node
            .create_publisher::<M>(&topic, None)
            .map_err(|e| e.to_string())?;
        Ok(Box::new(move |data: &[u8]| {
            let message = from_cdr::<M>(data).map_err(|e| e.to_string())?;
            publisher
                .publish(message)
                .map_err(|e| TopicError(e.to_string()))
        }))
    }
}

/// A node with one publisher per recorded topic of a known type.
pub struct Player {
    // Field order: publishers go before the node, the node before its context.
    publishers: Vec<Option<SendFn>>,
    _node: Node,
    _context: Context,
    /// Topics not played, and why (a type this build does not know).
    pub skipped: Vec<String>,
}

impl Player {
    /// Node `node_name` on `context`, publishing every topic of `bag` with its recorded QoS.
    pub fn new(context: Context, node_name: &str, bag: &Bag) -> Result<Player, PublishError> {
        let mut node = context
            .new_node(
                NodeName::new("/", node_name).map_err(|e| PublishError::Dds(format!("{e:?}")))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(|e| PublishError::Dds(e.to_string()))?;
        let mut publishers = Vec::new();
        let mut skipped = Vec::new();
        for topic in &bag.topics {
            let bad = |reason: String| PublishError::Topic {
                topic: topic.name.clone(),
                reason,
            };
            let name = Name::parse(&topic.name).map_err(|e| bad(format!("{e:?}")))?;
            let qos = topic
                .offered_qos
                .first()
                .map_or(QosProfile::publisher_default(), crate::qos::profile);
            let made = visit_type(
                &topic.type_name,
                MakePublisher {
                    node: &mut node,
                    name: &name,
                    qos,
                },
            );
            match made {
                Some(Ok(send)) => publishers.push(Some(send)),
                Some(Err(reason)) => return Err(bad(reason.0)),
                None => {
                    skipped.push(format!(
                        "{} ({}: unknown type)",
                        topic.name, topic.type_name
                    ));
                    publishers.push(None);
                }
            }
        }
        Ok(Player {
            publishers,
            _node: node,
            _context: context,
            skipped,
        })
    }

    /// Waits `delay` (for subscribers to be discovered), sends every message of `bag` at its
    /// recorded time scaled by `rate`, and stays `delay` longer for reliable deliveries to
    /// complete. Returns the messages sent per topic.
    pub fn play(
        &self,
        bag: &Bag,
        rate: f64,
        delay: Duration,
    ) -> Result<BTreeMap<String, u64>, PublishError> {
        std::thread::sleep(delay);
        let start = Instant::now();
        let mut sent = BTreeMap::new();
        for (at, i) in waam_messages::replay::schedule(bag, rate) {
            let message = &bag.messages[i];
            let Some(send) = &self.publishers[message.topic] else {
                continue;
            };
            if let Some(wait) = at.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
            let topic = &bag.topics[message.topic].name;
            send(&message.data).map_err(|reason| PublishError::Topic {
                topic: topic.clone(),
                reason: reason.0,
            })?;
            *sent.entry(topic.clone()).or_insert(0) += 1;
        }
        // Reliable samples go out (and are repeated) from DDS's own thread: stay a while
        // before the participant closes.
        std::thread::sleep(delay);
        Ok(sent)
    }
}

/// Subscribes to one topic and hands every message (as JSON) to `on_message` until `count`
/// arrived or `timeout` passed; returns how many arrived. The other end of [`Player`], for
/// checking a playback from the command line (`waam bag echo`) and in tests.
pub fn echo(
    context: &Context,
    topic: &str,
    type_name: &str,
    qos: &waam_rosbag::Qos,
    count: u64,
    timeout: Duration,
    on_message: &mut dyn FnMut(serde_json::Value),
) -> Result<u64, PublishError> {
    let bad = |reason: String| PublishError::Topic {
        topic: topic.to_string(),
        reason,
    };
    let name = Name::parse(topic).map_err(|e| bad(format!("{e:?}")))?;
    let mut node = context
        .new_node(
            NodeName::new("/", &format!("waam_echo_{}", std::process::id()))
                .map_err(|e| PublishError::Dds(format!("{e:?}")))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| PublishError::Dds(e.to_string()))?;
    struct Listen<'a> {
        node: &'a mut Node,
        name: &'a Name,
        qos: QosProfile,
        count: u64,
        timeout: Duration,
        on_message: &'a mut dyn FnMut(serde_json::Value),
    }
    impl TypeVisitor for Listen<'_> {
        type Output = Result<u64, TopicError>;
        fn visit<M>(self) -> Result<u64, TopicError>
        where
            M: AnyMessage,
        {
            let topic = self
                .node
                .create_topic(self.name, M::message_type_name(), &self.qos)
                .map_err(|e| e.to_string())?;
            let subscription = self
                .node
                .create_subscription::<M>(&topic, None)
                .map_err(|e| e.to_string())?;
            let deadline = Instant::now() + self.timeout;
            let mut got = 0;
            while got < self.count && Instant::now() < deadline {
                match subscription.take().map_err(|e| e.to_string())? {
                    Some((message, _)) => {
                        got += 1;
                        (self.on_message)(
                            serde_json::to_value(&message).map_err(|e| e.to_string())?,
                        );
                    }
                    None => std::thread::sleep(Duration::from_millis(5)),
                }
            }
            Ok(got)
        }
    }
    let listen = Listen {
        node: &mut node,
        name: &name,
        qos: crate::qos::profile(qos),
        count,
        timeout,
        on_message,
    };
    visit_type(type_name, listen)
        .ok_or_else(|| bad(format!("unknown type {type_name}")))?
        .map_err(|e| bad(e.0))
}
