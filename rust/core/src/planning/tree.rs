//! The search tree of one attempt ([`Tree`]: nodes, parents, the validated states of each edge,
//! lazy pruning, the nearest-neighbour index) and the path of a chain of nodes ([`extract`],
//! [`flatten`]). A tree may have several roots (RRT-Connect's goal tree: one per goal).

use super::{NearestNeighbors, NeighborIndex, Space};

/// Nodes a tree has room for when it is made (a free-space RRT-Connect tree rarely grows beyond:
/// its vectors are not reallocated while it grows to there).
const RESERVED_NODES: usize = 256;

/// The tree of one attempt: node configurations and, per node, the states on the edge from its
/// parent (exclusive of both ends, in the order parent to node).
pub(super) struct Tree {
    pub(super) nq: usize,
    pub(super) q: Vec<f64>,
    pub(super) parent: Vec<usize>,
    /// Each node's children as a list: its first child and each child's next sibling
    /// (`usize::MAX`: none), so that adding a node allocates nothing of its own.
    first_child: Vec<usize>,
    next_sibling: Vec<usize>,
    /// The edge from the parent has been validated (its states are stored).
    pub(super) validated: Vec<bool>,
    /// Pruned: an edge above it failed validation; never extended from again.
    dead: Vec<bool>,
    edge_start: Vec<usize>,
    edge_count: Vec<usize>,
    edge_states: Vec<f64>,
    nn: Box<dyn NearestNeighbors>,
    coords: Vec<f64>,
}

impl Tree {
    pub(super) fn node(&self, i: usize) -> &[f64] {
        &self.q[i * self.nq..(i + 1) * self.nq]
    }
    pub(super) fn len(&self) -> usize {
        self.parent.len()
    }
    /// An empty tree, with room for [`RESERVED_NODES`] nodes.
    pub(super) fn new(nq: usize, nv: usize, neighbors: NeighborIndex) -> Tree {
        let n = RESERVED_NODES;
        let mut nn = neighbors.build(nv);
        nn.reserve(n);
        Tree {
            nq,
            q: Vec::with_capacity(n * nq),
            parent: Vec::with_capacity(n),
            first_child: Vec::with_capacity(n),
            next_sibling: Vec::with_capacity(n),
            validated: Vec::with_capacity(n),
            dead: Vec::with_capacity(n),
            edge_start: Vec::with_capacity(n),
            edge_count: Vec::with_capacity(n),
            edge_states: Vec::new(),
            nn,
            coords: vec![0.0; nv],
        }
    }
    /// Add a node (a root when `parent` is `usize::MAX`); `edge`: the validated states from the
    /// parent, or None (validated later).
    pub(super) fn add(&mut self, space: &dyn Space, q: &[f64], parent: usize, edge: Option<&[f64]>) -> usize {
        let id = self.len();
        self.q.extend_from_slice(q);
        self.parent.push(parent);
        self.first_child.push(usize::MAX);
        self.next_sibling.push(usize::MAX);
        if parent != usize::MAX {
            self.next_sibling[id] = self.first_child[parent];
            self.first_child[parent] = id;
        }
        self.dead.push(false);
        self.validated.push(false);
        self.edge_start.push(0);
        self.edge_count.push(0);
        if let Some(e) = edge {
            self.set_edge(id, e);
        }
        space.coordinates(q, &mut self.coords);
        self.nn.add(&self.coords);
        id
    }
    pub(super) fn set_edge(&mut self, node: usize, states: &[f64]) {
        self.edge_start[node] = self.edge_states.len() / self.nq.max(1);
        self.edge_count[node] = states.len() / self.nq.max(1);
        self.edge_states.extend_from_slice(states);
        self.validated[node] = true;
    }
    /// The validated states of the edge from `node`'s parent to `node` (parent to node).
    pub(super) fn edge(&self, node: usize) -> &[f64] {
        let (s, n) = (self.edge_start[node], self.edge_count[node]);
        &self.edge_states[s * self.nq..(s + n) * self.nq]
    }
    /// Mark `node` and everything below it dead; returns how many nodes died.
    pub(super) fn prune(&mut self, node: usize) -> usize {
        let mut stack = vec![node];
        let mut n = 0;
        while let Some(i) = stack.pop() {
            if !self.dead[i] {
                self.dead[i] = true;
                n += 1;
            }
            let mut c = self.first_child[i];
            while c != usize::MAX {
                stack.push(c);
                c = self.next_sibling[c];
            }
        }
        n
    }
    /// The live node nearest to `q` (node 0 when every node is dead).
    pub(super) fn nearest(&mut self, space: &dyn Space, q: &[f64]) -> usize {
        space.coordinates(q, &mut self.coords);
        let dead = &self.dead;
        self.nn.nearest_where(&self.coords, &|i| !dead[i]).map(|(i, _)| i).unwrap_or(0)
    }
    /// Node indices from the root to `node`.
    pub(super) fn chain(&self, node: usize) -> Vec<usize> {
        let mut chain = Vec::new();
        self.chain_into(node, &mut chain);
        chain
    }
    /// [`chain`](Self::chain) into `chain` (cleared first; its memory reused).
    pub(super) fn chain_into(&self, node: usize, chain: &mut Vec<usize>) {
        chain.clear();
        chain.push(node);
        while let Some(&last) = chain.last() {
            match self.parent[last] {
                usize::MAX => break,
                p => chain.push(p),
            }
        }
        chain.reverse();
    }
}

/// The waypoints from the root to `goal_node` and, per waypoint after the first, the validated
/// states of the edge that leads to it.
pub(super) fn extract(tree: &Tree, goal_node: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let chain = tree.chain(goal_node);
    let waypoints = chain.iter().map(|&i| tree.node(i).to_vec()).collect();
    let edges = chain.iter().map(|&i| tree.edge(i).to_vec()).collect();
    (waypoints, edges)
}

/// Flatten waypoints and their edges into (waypoints, dense path).
pub(super) fn flatten(waypoints: &[Vec<f64>], edges: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let n_w: usize = waypoints.iter().map(Vec::len).sum();
    let mut w = Vec::with_capacity(n_w);
    let mut path = Vec::with_capacity(n_w + edges.iter().map(Vec::len).sum::<usize>());
    for (q, e) in waypoints.iter().zip(edges) {
        path.extend_from_slice(e);
        path.extend_from_slice(q);
        w.extend_from_slice(q);
    }
    (w, path)
}
