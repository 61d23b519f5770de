//! Plain sequential versions of every primitive: the oracles the tests compare the
//! device versions against. Same arguments, host slices.

/// `out[i] = in[0] ⊕ … ⊕ in[i]`.
pub fn inclusive_scan<T: Copy>(input: &[T], op: impl Fn(T, T) -> T) -> Vec<T> {
    let mut out = Vec::with_capacity(input.len());
    let mut acc: Option<T> = None;
    for &x in input {
        let v = acc.map_or(x, |a| op(a, x));
        out.push(v);
        acc = Some(v);
    }
    out
}

/// `out[0] = init`, `out[i] = init ⊕ in[0] ⊕ … ⊕ in[i-1]`.
pub fn exclusive_scan<T: Copy>(input: &[T], init: T, op: impl Fn(T, T) -> T) -> Vec<T> {
    let mut out = Vec::with_capacity(input.len());
    let mut acc = init;
    for &x in input {
        out.push(acc);
        acc = op(acc, x);
    }
    out
}

/// Folds `input` with `op`, starting from `init`.
pub fn reduce<T: Copy>(input: &[T], init: T, op: impl Fn(T, T) -> T) -> T {
    input.iter().fold(init, |a, &b| op(a, b))
}

/// Runs of equal consecutive keys and the reduction of each run's values.
pub fn reduce_by_key<K: Copy + PartialEq, V: Copy>(
    keys: &[K],
    values: &[V],
    op: impl Fn(V, V) -> V,
) -> (Vec<K>, Vec<V>) {
    let (mut ok, mut ov): (Vec<K>, Vec<V>) = (Vec::new(), Vec::new());
    for (&k, &v) in keys.iter().zip(values) {
        if ok.last() == Some(&k) {
            let last = ov.last_mut().unwrap();
            *last = op(*last, v);
        } else {
            ok.push(k);
            ov.push(v);
        }
    }
    (ok, ov)
}

/// Stable sort of (key, value) pairs by key bits `begin_bit..end_bit`.
pub fn sort_by_key_bits<V: Copy>(keys: &[u64], values: &[V], begin_bit: u32, end_bit: u32) -> (Vec<u64>, Vec<V>) {
    let width = end_bit - begin_bit;
    let mask = if width >= 64 { u64::MAX } else { (1u64 << width) - 1 };
    let mut idx: Vec<usize> = (0..keys.len()).collect();
    idx.sort_by_key(|&i| (keys[i] >> begin_bit) & mask); // `sort_by_key` is stable
    (idx.iter().map(|&i| keys[i]).collect(), idx.iter().map(|&i| values[i]).collect())
}

/// The elements for which `pred` holds, in order.
pub fn copy_if<T: Copy>(input: &[T], pred: impl Fn(T) -> bool) -> Vec<T> {
    input.iter().copied().filter(|&x| pred(x)).collect()
}

/// `output[i] = input[map[i]]`.
pub fn gather<T: Copy>(map: &[u32], input: &[T]) -> Vec<T> {
    map.iter().map(|&m| input[m as usize]).collect()
}

/// `output[map[i]] = input[i]`.
pub fn scatter<T: Copy>(input: &[T], map: &[u32], output: &mut [T]) {
    for (&x, &m) in input.iter().zip(map) {
        output[m as usize] = x;
    }
}

/// `start, start + step, ...`, `n` values.
pub fn sequence(n: usize, start: u32, step: u32) -> Vec<u32> {
    (0..n).map(|i| start.wrapping_add(step.wrapping_mul(i as u32))).collect()
}
