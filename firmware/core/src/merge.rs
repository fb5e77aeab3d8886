//! A board's step edges put in one CT order: each axis's edges staged in
//! its own order as its core decides them, then merged.
//!
//! A board whose pins follow one queue of edges in CT order (the Pico's
//! timer build: its edge interrupt drives each queue entry's pins at its
//! CT) needs every axis's edges in that order. Deciding them in it, one
//! edge at a time in the CT order of all the axes, costs a search for the
//! earliest axis at every edge. Instead each axis's edges are staged here
//! in its own order ([`EdgeMerge::stage`], [`EdgeMerge::stage_step`] for a
//! train's step and its pulse's end), and after each wake-up
//! [`EdgeMerge::merge`] hands out every staged edge before a CT, the next
//! wake-up of any axis, in CT order: a run of one axis's edges up to the
//! next other axis's, or every axis's edge at a CT at once, the changes at
//! one CT in one [`PinEdge`].
//!
//! An edge decided for a CT its axis has passed (a command's catch-up
//! after its axis's last edge, or before the board's timer: the main loop
//! fell behind) goes out as late as it must, and its axis's next edges one
//! lag behind while they come before the late one went out, so that late
//! steps keep their spacing; an edge that would still come before one
//! already merged goes at the last merged CT. Each such edge is reported
//! to the board's `on_shift`.

/// Edges staged per axis (a wake-up's steps, two edges each, and those an
/// earlier wake-up left for after the next). A power of two.
pub const STAGED: usize = 128;

/// The pins that change at one CT: what an edge queue holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PinEdge {
    /// The CT at which to drive them, its low 32 bits.
    pub ct: u32,
    /// Pins to drive high (a bit each).
    pub set: u32,
    /// Pins to drive low.
    pub clear: u32,
}

/// One pin's change, staged: its CT and the pins it sets or clears (one
/// of the two masks a bit, the other 0).
#[derive(Clone, Copy, Debug)]
struct Staged {
    ct: u64,
    set: u32,
    clear: u32,
}

/// A ring of staged edges, oldest first (one owner: plain indices).
#[derive(Clone, Debug)]
struct StagedRing {
    slots: [Staged; STAGED],
    /// The oldest edge's index, and one past the newest's (both wrap).
    head: usize,
    tail: usize,
}

impl StagedRing {
    const fn new() -> Self {
        const { assert!(STAGED.is_power_of_two()) };
        StagedRing {
            slots: [Staged {
                ct: 0,
                set: 0,
                clear: 0,
            }; STAGED],
            head: 0,
            tail: 0,
        }
    }

    #[inline(always)]
    fn len(&self) -> usize {
        self.tail.wrapping_sub(self.head)
    }

    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.head == self.tail
    }

    /// The oldest edge (the ring not empty).
    #[inline(always)]
    fn front(&self) -> Staged {
        self.slots[self.head & (STAGED - 1)]
    }

    #[inline(always)]
    fn pop(&mut self) {
        self.head = self.head.wrapping_add(1);
    }

    /// Adds `staged` (the ring not full).
    #[inline(always)]
    fn push(&mut self, staged: Staged) {
        self.slots[self.tail & (STAGED - 1)] = staged;
        self.tail = self.tail.wrapping_add(1);
    }
}

/// An axis whose edges went out later than decided: by how much, and
/// when its last late edge goes out.
#[derive(Clone, Copy, Debug, Default)]
struct Lag {
    lag: u64,
    last: u64,
}

/// One axis's staged edges, and its last.
#[derive(Clone, Debug)]
struct AxisStage {
    staged: StagedRing,
    /// The CT of the axis's last edge staged: it stays in this order.
    last_ct: u64,
    /// The pins that change at `last_ct`: another change of one of them
    /// goes a tick later (both at one CT would make no pulse).
    last_pins: u32,
    lag: Lag,
    /// A train's step whose pulse's end is staged with its rise: the CT
    /// its core decided for that end, and the pin. The core's own falling
    /// edge for it, if it comes, is that end already.
    ends_itself: Option<(u64, u32)>,
}

impl AxisStage {
    const fn new() -> Self {
        AxisStage {
            staged: StagedRing::new(),
            last_ct: 0,
            last_pins: 0,
            lag: Lag { lag: 0, last: 0 },
            ends_itself: None,
        }
    }

    /// The CT an edge of pin `pin` decided for CT `ct` goes out at: `ct`
    /// when it comes after the axis's last edge and `floor` (nothing more
    /// to look at); else as late as it must (see the module docs). The
    /// caller records it as the axis's last edge.
    #[inline(always)]
    fn place(&mut self, floor: u64, pin: u32, ct: u64, on_shift: fn(u32)) -> u64 {
        // An axis's lag applies only to its edges before its last late
        // one, which is at or before its last edge: none from there on. At
        // that edge's very CT only another change of the same pin is in
        // the way.
        let after = ct > self.last_ct || (ct == self.last_ct && self.last_pins & 1 << pin == 0);
        if after && ct >= floor {
            return ct;
        }
        self.place_late(floor, pin, ct, on_shift)
    }

    #[inline(never)]
    fn place_late(&mut self, floor: u64, pin: u32, ct: u64, on_shift: fn(u32)) -> u64 {
        let Lag { lag, last } = self.lag;
        let mut at = if ct < last { ct + lag } else { ct };
        at = at.max(self.last_ct).max(floor);
        if at == self.last_ct && self.last_pins & 1 << pin != 0 {
            at += 1;
        }
        if at != ct {
            on_shift(u32::try_from(at - ct).unwrap_or(u32::MAX));
        }
        self.lag = Lag {
            lag: at - ct,
            last: at,
        };
        at
    }
}

/// Every axis's staged edges, and the CT order they are merged into (see
/// the module docs). `AXES` axes, numbered from 0; output pins are
/// numbered 0 to 31 (the bits of [`PinEdge`]'s masks).
#[derive(Clone, Debug)]
pub struct EdgeMerge<const AXES: usize> {
    axes: [AxisStage; AXES],
    /// Each axis's oldest staged edge's CT (`u64::MAX`: none staged).
    heads: [u64; AXES],
    /// A step pulse's width, CT ticks.
    pulse: u64,
    /// The latest CT merged: the output stays in this order.
    last_ct: u64,
    /// Told of each edge placed later than its core decided, by how many
    /// ticks (the board counts them).
    on_shift: fn(u32),
}

impl<const AXES: usize> EdgeMerge<AXES> {
    /// No edge staged; `pulse`: a step pulse's width in CT ticks (a
    /// train's step is staged with its pulse's end, that long after its
    /// rise); `on_shift` is told of each edge that goes out later than
    /// decided.
    pub const fn new(pulse: u64, on_shift: fn(u32)) -> Self {
        EdgeMerge {
            axes: [const { AxisStage::new() }; AXES],
            heads: [u64::MAX; AXES],
            pulse,
            last_ct: 0,
            on_shift,
        }
    }

    /// A step pulse's width, CT ticks.
    pub fn pulse(&self) -> u64 {
        self.pulse
    }

    /// Stages pin `pin` of axis `axis` to `level`, decided for CT `ct`;
    /// `floor`: no edge goes out before it (the board's timer: an edge
    /// before it is late). Returns the CT it goes out at. A full ring (no
    /// merge for [`STAGED`] edges of one axis) hands its oldest edge to
    /// `emit` first, in its order; an axis past `AXES` stages nothing.
    pub fn stage(
        &mut self,
        axis: usize,
        pin: u32,
        level: bool,
        ct: u64,
        floor: u64,
        emit: &mut impl FnMut(PinEdge),
    ) -> u64 {
        let mask = 1 << (pin & 31);
        let (set, clear) = if level { (mask, 0) } else { (0, mask) };
        let on_shift = self.on_shift;
        let Some(state) = self.axes.get_mut(axis) else {
            return ct;
        };
        let at = state.place(floor, pin & 31, ct, on_shift);
        state.last_pins = if at == state.last_ct {
            state.last_pins | mask
        } else {
            mask
        };
        state.last_ct = at;
        state.ends_itself = None;
        if state.staged.len() == STAGED {
            self.emit_oldest(axis, emit);
        }
        self.push(axis, Staged { ct: at, set, clear });
        at
    }

    /// Stages a train's step on pin `pin` of axis `axis`, decided for CT
    /// `ct`: its rise and its pulse's end, the pulse's width later, with
    /// one placement. Returns the rise's CT. (As [`EdgeMerge::stage`]
    /// otherwise.)
    #[inline(always)]
    pub fn stage_step(
        &mut self,
        axis: usize,
        pin: u32,
        ct: u64,
        floor: u64,
        emit: &mut impl FnMut(PinEdge),
    ) -> u64 {
        let (pulse, on_shift) = (self.pulse, self.on_shift);
        let pin = pin & 31;
        let Some(state) = self.axes.get_mut(axis) else {
            return ct;
        };
        if STAGED - state.staged.len() < 2 {
            // A ring nearly full: one at a time.
            let at = self.stage(axis, pin, true, ct, floor, emit);
            self.stage(axis, pin, false, at + pulse, floor, emit);
            self.axes[axis].ends_itself = Some((ct + pulse, pin));
            return at;
        }
        let at = state.place(floor, pin, ct, on_shift);
        let end = at + pulse;
        // The pulse's end is the axis's last edge.
        let mask = 1 << pin;
        state.last_ct = end;
        state.last_pins = mask;
        state.ends_itself = Some((ct + pulse, pin));
        self.push(
            axis,
            Staged {
                ct: at,
                set: mask,
                clear: 0,
            },
        );
        // After the rise: the ring is not empty, its head stays.
        self.axes[axis].staged.push(Staged {
            ct: end,
            set: 0,
            clear: mask,
        });
        at
    }

    /// Whether the falling edge of pin `pin` of axis `axis` its core
    /// decided for CT `ct` is the end of a step's pulse already staged
    /// ([`EdgeMerge::stage_step`]); then its CT (and the edge is done).
    pub fn staged_end(&mut self, axis: usize, pin: u32, ct: u64) -> Option<u64> {
        let state = self.axes.get_mut(axis)?;
        if state.ends_itself == Some((ct, pin & 31)) {
            state.ends_itself = None;
            return Some(state.last_ct);
        }
        None
    }

    /// Hands every staged edge before CT `until` (`None`: every one) to
    /// `emit` in CT order, the changes at one CT in one [`PinEdge`], each
    /// CT after the last handed out (one before it, a late edge, goes at
    /// the last's CT and is reported to `on_shift`).
    pub fn merge(&mut self, until: Option<u64>, emit: &mut impl FnMut(PinEdge)) {
        let until = until.unwrap_or(u64::MAX);
        let on_shift = self.on_shift;
        let Self {
            axes,
            heads,
            last_ct,
            ..
        } = self;
        let mut last = *last_ct;
        // The pins changing at the last CT merged, not yet handed out:
        // the axes' changes at one CT go out in one write (one after
        // another, on the Pico a third axis's rise came a microsecond
        // late).
        let mut open: Option<PinEdge> = None;
        while let Some((first, second_ct)) = first_two(heads, until) {
            if second_ct == heads[first] {
                // Axes stepping together: every axis's edge at this CT at
                // once (one look at the axes for them all).
                let ct = second_ct;
                for (state, head) in axes.iter_mut().zip(heads.iter_mut()) {
                    if *head != ct {
                        continue;
                    }
                    let staged = take_front(&mut state.staged, head);
                    last = merge_in(emit, &mut open, staged, last, on_shift);
                }
                continue;
            }
            // Its edges up to the other's: a run of one axis at a time
            // (an emptied ring's head, `u64::MAX`, ends it too).
            let (ring, head) = (&mut axes[first].staged, &mut heads[first]);
            loop {
                let staged = take_front(ring, head);
                last = merge_in(emit, &mut open, staged, last, on_shift);
                if *head >= second_ct {
                    break;
                }
            }
        }
        if let Some(edge) = open {
            emit(edge);
        }
        *last_ct = last;
    }

    /// Adds `staged` to axis `axis`'s ring (not full).
    #[inline(always)]
    fn push(&mut self, axis: usize, staged: Staged) {
        let ring = &mut self.axes[axis].staged;
        if ring.is_empty() {
            self.heads[axis] = staged.ct;
        }
        ring.push(staged);
    }

    /// Hands axis `axis`'s oldest staged edge to `emit` now (its ring
    /// full), after every edge merged.
    #[cold]
    #[inline(never)]
    fn emit_oldest(&mut self, axis: usize, emit: &mut impl FnMut(PinEdge)) {
        let oldest = take_front(&mut self.axes[axis].staged, &mut self.heads[axis]);
        let mut open = None;
        self.last_ct = merge_in(emit, &mut open, oldest, self.last_ct, self.on_shift);
        if let Some(edge) = open {
            emit(edge);
        }
    }
}

/// Takes the oldest edge of `ring` (not empty), and sets `head`, its
/// axis's head, to the next one's CT (`u64::MAX`: none left).
#[inline(always)]
fn take_front(ring: &mut StagedRing, head: &mut u64) -> Staged {
    let staged = ring.front();
    ring.pop();
    *head = if ring.is_empty() {
        u64::MAX
    } else {
        ring.front().ct
    };
    staged
}

/// [`EdgeMerge::merge`]'s step for one staged edge: after every edge
/// merged (one before the last goes at the last's CT, reported), in one
/// `PinEdge` with the other axes' changes at its CT (`open`: the last
/// CT's, not yet handed out). Returns the CT merged.
#[inline(always)]
fn merge_in(
    emit: &mut impl FnMut(PinEdge),
    open: &mut Option<PinEdge>,
    staged: Staged,
    last: u64,
    on_shift: fn(u32),
) -> u64 {
    let at = if staged.ct >= last {
        staged.ct
    } else {
        on_shift(u32::try_from(last - staged.ct).unwrap_or(u32::MAX));
        last
    };
    let ct = at as u32;
    match open {
        // Another axis's change at the same CT (an axis's own never meet
        // at one: `AxisStage::place`).
        Some(edge) if edge.ct == ct => {
            edge.set |= staged.set;
            edge.clear |= staged.clear;
        }
        _ => {
            if let Some(edge) = open.replace(PinEdge {
                ct,
                set: staged.set,
                clear: staged.clear,
            }) {
                emit(edge);
            }
        }
    }
    at
}

/// Of the axes' oldest staged CTs, the index of the earliest if it comes
/// before `until`, and the next of the others (or `until` if that comes
/// first). Four values in registers, pairwise, where there are four (a
/// loop kept a running minimum in memory on the M0+; as 32-bit offsets
/// from the last CT merged, the conversions cost more than the 64-bit
/// comparisons they saved).
#[inline(always)]
fn first_two<const AXES: usize>(cts: &[u64; AXES], until: u64) -> Option<(usize, u64)> {
    if AXES == 4 {
        let (a, b, c, d) = (cts[0], cts[1], cts[2], cts[3]);
        let (low01, low01_ct, high01_ct) = if b < a { (1, b, a) } else { (0, a, b) };
        let (low23, low23_ct, high23_ct) = if d < c { (3, d, c) } else { (2, c, d) };
        let (first, first_ct, second_ct) = if low23_ct < low01_ct {
            (low23, low23_ct, low01_ct.min(high23_ct))
        } else {
            (low01, low01_ct, low23_ct.min(high01_ct))
        };
        return (first_ct < until).then_some((first, second_ct.min(until)));
    }
    let (mut first, mut first_ct, mut second_ct) = (AXES, until, until);
    for (index, &ct) in cts.iter().enumerate() {
        if ct < first_ct {
            (first, first_ct, second_ct) = (index, ct, first_ct);
        } else if ct < second_ct {
            second_ct = ct;
        }
    }
    (first < AXES).then_some((first, second_ct))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::cell::RefCell;

    thread_local! {
        static SHIFTS: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
    }

    fn record_shift(ticks: u32) {
        SHIFTS.with(|shifts| shifts.borrow_mut().push(ticks));
    }

    /// One operation on the merge, as a board makes them.
    #[derive(Clone, Debug)]
    enum Op {
        /// A train's step on axis `axis` (pin `2·axis`), `gap` ticks after
        /// the axis's last decided edge (its pulse's end, after a step).
        Step { axis: usize, gap: u64 },
        /// A change of the axis's second pin (`2·axis + 1`), `gap` after.
        Edge { axis: usize, gap: u64, level: bool },
        /// A merge up to the next edge any axis may decide, less `back`
        /// (a board merges up to the next wake-up of any axis).
        Merge { back: u64 },
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            4 => (0usize..4, 1u64..40).prop_map(|(axis, gap)| Op::Step { axis, gap }),
            1 => (0usize..4, 1u64..40, any::<bool>()).prop_map(|(axis, gap, level)| Op::Edge { axis, gap, level }),
            1 => (0u64..60).prop_map(|back| Op::Merge { back }),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Whatever the axes stage and whenever the board merges: the
        /// entries come out in strictly rising CTs, every staged edge
        /// once (merged while before the merge's CT, the rest by the last
        /// merge), each axis's in its own order, an axis's edges never
        /// sooner than decided nor two changes of one pin at one CT, each
        /// step's pulse its width long.
        #[test]
        fn merged_edges_keep_every_axis_in_ct_order(ops in prop::collection::vec(op(), 1..200)) {
            const PULSE: u64 = 5;
            SHIFTS.with(|shifts| shifts.borrow_mut().clear());
            let mut merge = EdgeMerge::<4>::new(PULSE, record_shift);
            let mut out: Vec<PinEdge> = Vec::new();
            // The model: every edge as placed (CT, pin, level), in order.
            let mut placed: Vec<(u64, u32, bool)> = Vec::new();
            // Each axis's last decided CT (the core's, before placement).
            let mut decided = [100u64; 4];
            let floor = 0;
            for op in ops {
                let mut emit = |edge: PinEdge| out.push(edge);
                match op {
                    Op::Step { axis, gap } => {
                        let ct = decided[axis] + gap;
                        let pin = 2 * axis as u32;
                        let at = merge.stage_step(axis, pin, ct, floor, &mut emit);
                        prop_assert!(at >= ct, "a step went out before its CT");
                        placed.push((at, pin, true));
                        placed.push((at + PULSE, pin, false));
                        decided[axis] = ct + PULSE;
                        // The core's own falling edge is the end staged.
                        prop_assert_eq!(merge.staged_end(axis, pin, ct + PULSE), Some(at + PULSE));
                    }
                    Op::Edge { axis, gap, level } => {
                        let ct = decided[axis] + gap;
                        let pin = 2 * axis as u32 + 1;
                        let at = merge.stage(axis, pin, level, ct, floor, &mut emit);
                        prop_assert!(at >= ct);
                        placed.push((at, pin, level));
                        decided[axis] = ct;
                    }
                    Op::Merge { back } => {
                        // No axis decides an edge before its last one's CT
                        // plus one: every edge before that is final.
                        let next = decided.iter().min().unwrap() + 1;
                        let until = next.saturating_sub(back);
                        let mut merged = Vec::new();
                        merge.merge(Some(until), &mut |edge| merged.push(edge));
                        // Everything merged comes before `until`.
                        for edge in &merged {
                            prop_assert!(u64::from(edge.ct) < until);
                        }
                        out.extend(merged);
                    }
                }
            }
            merge.merge(None, &mut |edge| out.push(edge));
            // Strictly rising CTs: the changes at one CT in one entry.
            for pair in out.windows(2) {
                prop_assert!(pair[0].ct < pair[1].ct, "{:?}", pair);
            }
            // No entry sets and clears one pin.
            for edge in &out {
                prop_assert_eq!(edge.set & edge.clear, 0);
            }
            // No shift here (no floor, each axis's edges after its last,
            // every merge before the next edge decided): each pin's
            // changes as decided, in order.
            prop_assert!(SHIFTS.with(|shifts| shifts.borrow().is_empty()));
            for pin in 0..8u32 {
                let expected: Vec<(u32, bool)> = placed
                    .iter()
                    .filter(|&&(_, p, _)| p == pin)
                    .map(|&(at, _, level)| (at as u32, level))
                    .collect();
                let seen: Vec<(u32, bool)> = out
                    .iter()
                    .filter(|edge| (edge.set | edge.clear) & 1 << pin != 0)
                    .map(|edge| (edge.ct, edge.set & 1 << pin != 0))
                    .collect();
                prop_assert_eq!(seen, expected, "pin {}", pin);
            }
        }

        /// An edge decided for a CT already merged (a command's catch-up)
        /// goes out at the last merged CT, reported; an axis's edges before
        /// the board's timer go out at it, and its next ones one lag
        /// behind while they come before the late one went out.
        #[test]
        fn late_edges_go_out_late_and_keep_their_spacing(late in 1u64..50, period in 8u64..40, steps in 1usize..10) {
            const PULSE: u64 = 5;
            SHIFTS.with(|shifts| shifts.borrow_mut().clear());
            let mut merge = EdgeMerge::<4>::new(PULSE, record_shift);
            let mut out = Vec::new();
            let start = 1_000;
            let floor = start + late;
            let mut rises = Vec::new();
            for step in 0..steps {
                let ct = start + step as u64 * period;
                rises.push(merge.stage_step(0, 0, ct, floor, &mut |edge| out.push(edge)));
            }
            merge.merge(None, &mut |edge| out.push(edge));
            // The first at the floor, the others one lag behind while they
            // come before the late one (the lag ends at a gap longer than
            // it), never sooner than decided, spacing kept.
            prop_assert_eq!(rises[0], floor);
            for pair in rises.windows(2) {
                // After the last pulse's end: a low between pulses.
                prop_assert!(pair[1] > pair[0] + PULSE);
            }
            for (step, &at) in rises.iter().enumerate() {
                prop_assert!(at >= start + step as u64 * period);
            }
            prop_assert!(SHIFTS.with(|shifts| !shifts.borrow().is_empty()));
            for pair in out.windows(2) {
                prop_assert!(pair[0].ct < pair[1].ct);
            }
            // Then a command's edge for a CT the merge has passed.
            let before = SHIFTS.with(|shifts| shifts.borrow().len());
            let last = u64::from(out.last().unwrap().ct);
            merge.stage(1, 3, true, start, 0, &mut |edge| out.push(edge));
            merge.merge(None, &mut |edge| out.push(edge));
            prop_assert_eq!(u64::from(out.last().unwrap().ct), last);
            prop_assert_eq!(SHIFTS.with(|shifts| shifts.borrow().len()), before + 1);
        }
    }

    #[test]
    fn axes_stepping_together_share_one_entry_a_ct() {
        let mut merge = EdgeMerge::<4>::new(5, record_shift);
        let mut out = Vec::new();
        for axis in 0..4 {
            merge.stage_step(axis, 2 * axis as u32, 100, 0, &mut |edge| out.push(edge));
        }
        merge.merge(None, &mut |edge| out.push(edge));
        assert_eq!(
            out,
            [
                PinEdge {
                    ct: 100,
                    set: 0b0101_0101,
                    clear: 0
                },
                PinEdge {
                    ct: 105,
                    set: 0,
                    clear: 0b0101_0101
                },
            ]
        );
    }

    #[test]
    fn a_full_ring_hands_its_oldest_edge_out_in_order() {
        let mut merge = EdgeMerge::<4>::new(5, record_shift);
        let mut out = Vec::new();
        for step in 0..STAGED as u64 {
            merge.stage_step(0, 0, 100 + 10 * step, 0, &mut |edge| out.push(edge));
        }
        // The ring held STAGED edges: the last steps pushed the first out.
        assert!(!out.is_empty());
        merge.merge(None, &mut |edge| out.push(edge));
        assert_eq!(out.len(), 2 * STAGED);
        for pair in out.windows(2) {
            assert!(pair[0].ct < pair[1].ct);
        }
    }

    #[test]
    fn first_two_finds_the_earliest_and_the_next() {
        let cts = [40, 10, u64::MAX, 30];
        assert_eq!(first_two(&cts, 100), Some((1, 30)));
        assert_eq!(first_two(&cts, 20), Some((1, 20)));
        assert_eq!(first_two(&cts, 10), None);
        assert_eq!(first_two(&[7u64, 7, 9], 100), Some((0, 7)));
        assert_eq!(first_two(&[u64::MAX; 4], u64::MAX), None);
    }
}
