#!/usr/bin/env python3
"""Instructions of a fused G2P2G kernel, from its SASS (`nvdisasm -g` of the cubin that
scripts/kernel_sass.sh makes): the static count, and an estimate of the instructions one warp
issues per warp-list entry, by kind, at R shuffle rounds of the warp reduction.

The estimate: the basic blocks of the entry loop (the longest backward branch) once; blocks
inside the scatter's row and plane loops (backward branches whose body holds SHFL.DOWN) three
times per enclosing loop; the rare blocks left out (the in-warp sort network and the particle
permutation: SHFL.BFLY / SHFL.IDX; the bad-particle atomicMin: REDG.E.MIN); blocks of shuffle
rounds past R (a SHFL.DOWN by 2^R or more) left out. Divergent branches count both sides (a warp
issues both). Usage: sass_entry_count.py DISASM KERNEL [R ...]
"""
import collections
import re
import sys

INT = {"IMAD", "IADD3", "LEA", "LOP3", "SHF", "SEL", "ISETP", "VIMNMX", "IABS", "PRMT", "FLO", "POPC",
       "BREV", "IMNMX", "SGXT", "BMSK", "I2FP", "PLOP3", "R2UR", "F2I", "I2F", "VIADD", "P2R", "R2P"}
FP = {"FFMA", "FMUL", "FADD", "FMNMX", "FSETP", "MUFU", "FRND", "FSEL", "FCHK", "FSET", "DFMA", "DMUL",
      "DADD", "DSETP", "DMNMX", "DSEL", "F2F"}
KINDS = [("mov", {"HFMA2", "MOV", "CS2R", "S2R", "S2UR"}), ("int", INT), ("fp", FP),
         ("load", {"LDG", "LDL", "LDC", "ULDC", "LDS"}), ("store", {"STG", "STL", "STS"}),
         ("atomic", {"RED", "REDG", "ATOM", "ATOMG"}), ("shfl", {"SHFL"}),
         ("vote", {"VOTE", "VOTEU", "REDUX", "MATCH"}),
         ("branch", {"BRA", "BSSY", "BSYNC", "EXIT", "WARPSYNC", "BREAK", "CALL", "RET", "NOP"})]


def kind(op):
    base = op.split(".")[0]
    if op.startswith("IMAD.MOV"):
        return "mov"
    for k, names in KINDS:
        if base in names:
            return k
    return "uniform" if base.startswith("U") else "other"


def kernel_rows(path, kernel):
    """(address, opcode, text) of the kernel's instructions and its labels (address None)."""
    rows, inside = [], False
    for line in open(path):
        if line.startswith("//----") and ".text." in line:
            inside = re.search(r"\.text\.(\S+)", line).group(1) == kernel
            continue
        if not inside:
            continue
        m = re.match(r"\s*/\*([0-9a-f]{4,})\*/\s+(.*?);", line)
        if m:
            text = m.group(2)
            words = text.split()
            op = words[1] if words[0].startswith("@") else words[0]
            rows.append((int(m.group(1), 16), op, text))
            continue
        m = re.match(r"^(\.L_x_\d+):", line)
        if m:
            rows.append((None, m.group(1), ""))
    return rows


def blocks(rows):
    """Basic blocks: (labels, instructions), split at labels and after branches."""
    out, cur = [], ([], [])
    for a, op, text in rows:
        if a is None:
            if cur[1]:
                out.append(cur)
                cur = ([], [])
            cur[0].append(op)
            continue
        cur[1].append((a, op, text))
        if op.startswith("BRA") or op.startswith("EXIT"):
            out.append(cur)
            cur = ([], [])
    if cur[1]:
        out.append(cur)
    return out


def estimate(rows, rounds):
    bl = blocks(rows)
    at = {label: b[1][0][0] for b in bl for label in b[0]}
    ins = [r for r in rows if r[0] is not None]
    loops = []
    for a, op, text in ins:
        m = re.search(r"BRA `\((\.L_x_\d+)\)", text)
        if m and at.get(m.group(1), a) < a:
            loops.append((at[m.group(1)], a))
    entry = max(loops, key=lambda x: x[1] - x[0])
    inner = [lp for lp in loops if lp != entry and any("SHFL.DOWN" in t for a, _, t in ins if lp[0] <= a <= lp[1])]
    by = collections.Counter()
    for _, body in bl:
        a0 = body[0][0]
        if not entry[0] <= a0 <= entry[1]:
            continue
        text = " ".join(t for _, _, t in body)
        if "SHFL.BFLY" in text or "SHFL.IDX" in text or "REDG.E.MIN" in text:
            continue
        shifts = [int(s, 16) for s in re.findall(r"SHFL\.DOWN \S+ \S+ \S+ (0x[0-9a-f]+)", text)]
        if shifts and max(shifts) >= 1 << rounds:
            continue
        mult = 3 ** sum(1 for lp in inner if lp[0] <= a0 <= lp[1])
        for _, op, _ in body:
            by[kind(op)] += mult
    return by


def main():
    path, kernel = sys.argv[1], sys.argv[2]
    rows = kernel_rows(path, kernel)
    ins = [r for r in rows if r[0] is not None]
    if not ins:
        sys.exit(f"kernel {kernel} not found in {path}")
    static = collections.Counter(kind(op) for _, op, _ in ins)
    print(f"{kernel}: {len(ins)} static instructions: " + " ".join(f"{k}={v}" for k, v in sorted(static.items())))
    for r in [int(x) for x in sys.argv[3:]] or [0, 3, 4]:
        by = estimate(rows, r)
        print(f"  per warp entry, R = {r}: {sum(by.values())}: " + " ".join(f"{k}={v}" for k, v in sorted(by.items())))


if __name__ == "__main__":
    main()
