//! What an evaluation costs on a GPU, as far as it can be told without one: the SPIR-V instructions
//! of `nbrdf_eval` and everything it calls, and the networks' multiply-adds.

use std::collections::{BTreeSet, HashMap};

use crate::{lang, Error, Shader};

/// The cost figures of an exported shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cost {
    /// SPIR-V instructions of the whole module (all entry points, types, constants).
    pub module_instructions: usize,
    /// SPIR-V instructions of `nbrdf_eval` and the functions it calls (each counted once): the static
    /// size of one evaluation's code; loops (storage-buffer weights) run theirs many times.
    pub eval_instructions: usize,
    /// Multiply-adds of the networks per `nbrdf_eval` (the dynamic work that dominates).
    pub macs: usize,
    /// The SPIR-V size in bytes.
    pub spirv_bytes: usize,
}

const OP_NAME: u32 = 5;
const OP_FUNCTION: u32 = 54;
const OP_FUNCTION_END: u32 = 56;
const OP_FUNCTION_CALL: u32 = 57;

impl Cost {
    /// Measures a shader: translates it to SPIR-V and counts.
    pub fn of(shader: &Shader) -> Result<Cost, Error> {
        let (module, info) = lang::parse_wgsl(&shader.wgsl)?;
        let words = lang::spirv_words(&module, &info)?;
        let (total, per_function, calls, names) = scan(&words);
        let eval = names.iter().find(|(_, n)| n.as_str() == "nbrdf_eval").map(|(id, _)| *id);
        let eval_instructions = match eval {
            Some(root) => {
                let mut seen = BTreeSet::new();
                let mut stack = vec![root];
                while let Some(f) = stack.pop() {
                    if seen.insert(f) {
                        stack.extend(calls.get(&f).into_iter().flatten().copied());
                    }
                }
                seen.iter().map(|f| per_function.get(f).copied().unwrap_or(0)).sum()
            }
            None => 0,
        };
        Ok(Cost { module_instructions: total, eval_instructions, macs: shader.macs, spirv_bytes: words.len() * 4 })
    }
}

type Scan = (usize, HashMap<u32, usize>, HashMap<u32, Vec<u32>>, HashMap<u32, String>);

/// Instructions in all, per function (by result id), the functions each one calls, and the debug
/// names of ids.
fn scan(words: &[u32]) -> Scan {
    let (mut total, mut per, mut calls, mut names) = (0, HashMap::new(), HashMap::<u32, Vec<u32>>::new(), HashMap::new());
    let mut at = 5; // the header
    let mut current = None;
    while at < words.len() {
        let (count, op) = ((words[at] >> 16) as usize, words[at] & 0xffff);
        if count == 0 || at + count > words.len() {
            break;
        }
        let operands = &words[at + 1..at + count];
        total += 1;
        match op {
            OP_NAME if !operands.is_empty() => {
                let bytes: Vec<u8> = operands[1..].iter().flat_map(|w| w.to_le_bytes()).take_while(|&b| b != 0).collect();
                names.insert(operands[0], String::from_utf8_lossy(&bytes).into_owned());
            }
            OP_FUNCTION if operands.len() >= 2 => current = Some(operands[1]),
            OP_FUNCTION_END => current = None,
            OP_FUNCTION_CALL if operands.len() >= 3 => {
                if let Some(f) = current {
                    calls.entry(f).or_default().push(operands[2]);
                }
            }
            _ => {}
        }
        if let Some(f) = current {
            *per.entry(f).or_insert(0) += 1;
        }
        at += count;
    }
    (total, per, calls, names)
}
