#!/usr/bin/env bash
# End-to-end tests of the bpx command-line tool: output, parsing, errors and exit codes.
# usage: test_cli.sh PATH/TO/bpx [SCRATCH_DIR]
# Runs every case, prints each failure with its output, and exits 1 if any failed.
set -euo pipefail

if [[ $# -lt 1 ]]; then
    echo "usage: $0 PATH/TO/bpx [SCRATCH_DIR]" >&2
    exit 2
fi
bpx=$1
if [[ $# -ge 2 ]]; then
    tmp=$2
    rm -rf "$tmp"
    mkdir -p "$tmp"
else
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
fi
if [[ ! -x $bpx ]]; then
    echo "FAIL: $bpx is not an executable" >&2
    exit 1
fi

cases=0
failures=0
case_name=""

begin() {
    case_name=$1
    cases=$((cases + 1))
}

fail() {
    failures=$((failures + 1))
    echo "FAIL: $case_name: $*" >&2
    echo "  exit status: $rc" >&2
    echo "  --- stdout (first 5 lines):" >&2
    head -n 5 "$tmp/out" | sed 's/^/  | /' >&2 || true
    echo "  --- stderr:" >&2
    sed 's/^/  | /' "$tmp/err" >&2 || true
}

# run ARGS...: runs bpx; stdout and stderr land in $tmp/out and $tmp/err, the status in $rc.
run() {
    rc=0
    "$bpx" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?
}

# run_in FILE ARGS...: as run, with FILE on standard input.
run_in() {
    local input=$1
    shift
    rc=0
    "$bpx" "$@" <"$input" >"$tmp/out" 2>"$tmp/err" || rc=$?
}

# expect_ok EXPECTED_FILE: success, stdout equal to the file, nothing on stderr.
expect_ok() {
    if [[ $rc -ne 0 ]]; then
        fail "expected exit 0"
    elif [[ -s $tmp/err ]]; then
        fail "expected empty stderr"
    elif ! cmp -s "$1" "$tmp/out"; then
        fail "stdout differs from $(basename "$1"):" \
            "$(diff "$1" "$tmp/out" | head -n 6 | tr '\n' ' ')"
    fi
}

# expect_error STATUS TEXT...: that exit status, empty stdout, stderr containing every TEXT.
expect_error() {
    local status=$1
    shift
    if [[ $rc -ne $status ]]; then
        fail "expected exit $status"
        return
    fi
    if [[ -s $tmp/out ]]; then
        fail "expected empty stdout"
        return
    fi
    local text
    for text in "$@"; do
        if ! grep -qF -- "$text" "$tmp/err"; then
            fail "stderr lacks: $text"
            return
        fi
    done
}

# expect_help: exit 0, usage on stdout, nothing on stderr.
expect_help() {
    if [[ $rc -ne 0 ]]; then
        fail "expected exit 0"
    elif ! grep -q "usage" "$tmp/out"; then
        fail "expected usage text on stdout"
    elif [[ -s $tmp/err ]]; then
        fail "expected empty stderr"
    fi
}

# ---------------------------------------------------------------------------------------------
# A small scene with known pairs. Closed intervals: boxes that only touch overlap.
#   0 [0,1]^3            1 [1,2]^3 touches 0 at a corner     2 inside 0
#   3 far away           4 [-1,0]^3 touches 0 at the origin  5 a point inside 1
#   6 the point at the origin (with -0): in 0 and 4
{
    printf '%s\r\n' '# a comment line, CRLF ends'
    printf '%s\n' \
        '0,0,0,1,1,1' \
        '  1 , 1,1,  2,2 ,2   # trailing comment' \
        '' \
        '   '
    printf '\t\n0.5,\t0.5,0.5,0.6,0.6,0.6\r\n'
    printf '%s\n' \
        '5e0,5,5,6,6,6' \
        '# between' \
        '-1,-1,-1,0,0,0' \
        '1.5,1.5,1.5,1.5,1.5,1.5#no space before comment'
    printf -- '-0,0,0,0,0,-0' # no newline at the end of the file
} >"$tmp/small.csv"
printf '%s\n' '0 1' '0 2' '0 4' '0 6' '1 5' '4 6' >"$tmp/small.expected"
echo 6 >"$tmp/small.count"
: >"$tmp/empty.expected"
echo 0 >"$tmp/zero.count"

begin "pairs of the small scene"
run pairs "$tmp/small.csv"
expect_ok "$tmp/small.expected"

begin "pairs from standard input"
run_in "$tmp/small.csv" pairs -
expect_ok "$tmp/small.expected"

begin "pairs through a pipe"
rc=0
# shellcheck disable=SC2002 # a pipe, unlike a redirected file, cannot seek
cat "$tmp/small.csv" | "$bpx" pairs - >"$tmp/out" 2>"$tmp/err" || rc=$?
expect_ok "$tmp/small.expected"

begin "--count"
run pairs --count "$tmp/small.csv"
expect_ok "$tmp/small.count"

begin "--count after FILE, stdin"
run_in "$tmp/small.csv" pairs - --count
expect_ok "$tmp/small.count"

begin "flags before and after FILE, --flag=value and --flag value"
run pairs --backend=reference "$tmp/small.csv" --threads 1
expect_ok "$tmp/small.expected"

begin "-- ends the options"
run pairs --count -- "$tmp/small.csv"
expect_ok "$tmp/small.count"

begin "empty file"
: >"$tmp/empty.csv"
run pairs "$tmp/empty.csv"
expect_ok "$tmp/empty.expected"

begin "empty file, --count"
run pairs --count "$tmp/empty.csv"
expect_ok "$tmp/zero.count"

begin "comments and blank lines only"
printf '# nothing\n\n   \n\t# here\r\n' >"$tmp/comments.csv"
run pairs --count "$tmp/comments.csv"
expect_ok "$tmp/zero.count"

begin "one box has no pairs"
echo '0,0,0,1,1,1' >"$tmp/one.csv"
run pairs "$tmp/one.csv"
expect_ok "$tmp/empty.expected"

begin "underflow to zero is accepted, exponents and signs parse"
printf '%s\n' '0,0,0,1e-50,1,1' '-0.0,+0,0E0,0,0,0' '2,2,2,.3e1,3.,3' >"$tmp/tiny.csv"
printf '%s\n' '0 1' >"$tmp/tiny.expected"
run pairs "$tmp/tiny.csv"
expect_ok "$tmp/tiny.expected"

begin "lines longer than the read buffer"
pad=$(head -c 300000 /dev/zero | tr '\0' ' ')
printf '%s0,0,0,1,1,1%s\n# %sx\n1,1,1,2,2,2\n' "$pad" "$pad" "$pad" >"$tmp/long.csv"
printf '%s\n' '0 1' >"$tmp/long.expected"
run pairs "$tmp/long.csv"
expect_ok "$tmp/long.expected"

# ---------------------------------------------------------------------------------------------
# A random scene of integer-cornered boxes (many exact touches), checked against an awk brute
# force, then every available backend, thread count and SIMD width must print the same bytes.
awk 'BEGIN {
    srand(7)
    for (k = 0; k < 300; k++) {
        for (a = 0; a < 3; a++) { lo[a] = int(rand() * 40); hi[a] = lo[a] + int(rand() * 4) }
        printf "%d,%d,%d,%d,%d,%d\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    }
}' >"$tmp/random.csv"
awk -F, '{ for (a = 1; a <= 6; a++) c[NR - 1, a] = $a + 0; n = NR }
END {
    for (i = 0; i < n; i++) for (j = i + 1; j < n; j++) {
        hit = 1
        for (a = 1; a <= 3; a++)
            if (c[i, a] > c[j, a + 3] || c[j, a] > c[i, a + 3]) hit = 0
        if (hit) print i, j
    }
}' "$tmp/random.csv" >"$tmp/random.expected"

begin "random scene matches a brute force"
run pairs "$tmp/random.csv"
expect_ok "$tmp/random.expected"
if [[ ! -s $tmp/random.expected ]]; then
    fail "the random scene has no pairs; the test proves little"
fi

begin "bpx backends"
run backends
if [[ $rc -ne 0 || -s $tmp/err ]]; then
    fail "expected exit 0 and empty stderr"
fi
awk '$2 != "available" && $2 != "unavailable" { bad = 1 } END { exit bad }' "$tmp/out" ||
    fail "every line must be: NAME available|unavailable [DETAIL]"
for name in auto reference brute; do
    awk -v n="$name" '$1 == n { found = 1 } END { exit !found }' "$tmp/out" ||
        fail "backend $name not listed"
done
awk '$2 == "available" { print $1 }' "$tmp/out" >"$tmp/backends.available"
[[ -s $tmp/backends.available ]] || fail "no backend is available"

begin "bpx backends --simd"
run backends --simd
if [[ $rc -ne 0 || -s $tmp/err ]]; then
    fail "expected exit 0 and empty stderr"
fi
awk '$1 == "scalar" && $2 == "supported" { found = 1 } END { exit !found }' "$tmp/out" ||
    fail "scalar must be listed as supported"
awk '$2 == "supported" && $1 != "auto" { print $1 }' "$tmp/out" >"$tmp/simd.supported"

while read -r backend; do
    begin "backend $backend: small scene"
    run pairs "$tmp/small.csv" --backend "$backend"
    expect_ok "$tmp/small.expected"
    for threads in 1 3; do
        begin "backend $backend, $threads threads: random scene"
        run pairs --backend="$backend" --threads="$threads" "$tmp/random.csv"
        expect_ok "$tmp/random.expected"
    done
done <"$tmp/backends.available"

if grep -qx brute "$tmp/backends.available"; then
    while read -r simd; do
        begin "backend brute, simd $simd: random scene"
        run pairs --backend brute --simd "$simd" --threads 2 "$tmp/random.csv"
        expect_ok "$tmp/random.expected"
    done <"$tmp/simd.supported"
fi

# ---------------------------------------------------------------------------------------------
# A million pairs: the output goes through several buffer flushes and must stay exact.
awk 'BEGIN { for (k = 0; k < 1500; k++) print "0,0,0,1,1,1" }' >"$tmp/dense.csv"
awk 'BEGIN { for (i = 0; i < 1500; i++) for (j = i + 1; j < 1500; j++) print i, j }' \
    >"$tmp/dense.expected"
echo 1124250 >"$tmp/dense.count"

begin "1124250 pairs"
run pairs "$tmp/dense.csv"
expect_ok "$tmp/dense.expected"

begin "1124250 pairs, --count"
run pairs "$tmp/dense.csv" --count
expect_ok "$tmp/dense.count"

if [[ -w /dev/full ]]; then
    begin "write error"
    rc=0
    "$bpx" pairs "$tmp/dense.csv" >/dev/full 2>"$tmp/err" || rc=$?
    : >"$tmp/out"
    expect_error 1 "write error"
fi

# ---------------------------------------------------------------------------------------------
# Malformed input: exit 1, nothing on stdout, and a message naming the file, line and field.
# Each bad line is line 4, after a comment, a good box and a blank line.
bad_case() {
    local name=$1 line=$2
    shift 2
    begin "malformed: $name"
    printf '# header\n0,0,0,1,1,1\n\n%s\n2,2,2,3,3,3\n' "$line" >"$tmp/bad.csv"
    run pairs "$tmp/bad.csv"
    expect_error 1 "bad.csv:4:" "$@"
}

bad_case "5 fields" '0,0,0,1,1' "found 5"
bad_case "7 fields" '0,0,0,1,1,1,1' "found 7"
bad_case "trailing comma" '0,0,0,1,1,1,' "found 7"
bad_case "1 field" '42' "found 1"
bad_case "empty field" '0,,0,1,1,1' "field 2 (min y): empty"
bad_case "blank field" '0,0,0,1,1,  ' "field 6 (max z): empty"
bad_case "commas only" ',,,,,' "field 1 (min x): empty"
bad_case "garbage" '0,0,0,abc,1,1' 'field 4 (max x): not a number: "abc"'
bad_case "trailing garbage" '0,0,0,1.5x,1,1' 'field 4 (max x): not a number: "1.5x"'
bad_case "two numbers in a field" '0,0,0,1 2,1,1' 'field 4 (max x): not a number: "1 2"'
bad_case "semicolons" '0;0;0;1;1;1' "found 1"
bad_case "nan" '0,nan,0,1,1,1' "field 2 (min y)" "nan"
bad_case "NAN" '0,0,0,1,NAN,1' "field 5 (max y)" "NAN"
bad_case "inf" '0,0,0,1,inf,1' "field 5 (max y)" "inf"
bad_case "-infinity" '-infinity,0,0,1,1,1' "field 1 (min x)" "-infinity"
bad_case "1e39" '0,0,0,1,1,1e39' "field 6 (max z)" "1e39"
bad_case "-1e39" '0,0,-1e39,1,1,1' "field 3 (min z)" "-1e39"
bad_case "min > max" '0,2.5,0,1,1,1' "min y (2.5) > max y (1)"
bad_case "min > max on x" '3,0,0,-3,1,1' "min x (3) > max x (-3)"

begin "malformed: exact message"
printf '0,0,0,1,1,1\n0,0,0,abc,1,1\n' >"$tmp/boxes.csv"
run pairs "$tmp/boxes.csv"
expect_error 1
if [[ $rc -eq 1 ]] && ! grep -qxF \
    "bpx pairs: $tmp/boxes.csv:2: field 4 (max x): not a number: \"abc\"" "$tmp/err"; then
    fail "unexpected message"
fi

begin "malformed: line numbers count CRLF lines, comments and blanks"
printf '# c\r\n\r\n0,0,0,1,1,1\r\n  \r\n0,0,0,1,1\r\n' >"$tmp/crlf.csv"
run pairs "$tmp/crlf.csv"
expect_error 1 "crlf.csv:5:" "found 5"

# Excel's "CSV UTF-8" starts with a byte-order mark; once skipped, the rest is an ordinary file.
begin "pairs: UTF-8 byte-order mark at the start"
{
    printf '\xef\xbb\xbf'
    cat "$tmp/small.csv"
} >"$tmp/bom.csv"
run pairs "$tmp/bom.csv"
expect_ok "$tmp/small.expected"

begin "pairs: byte-order mark before a comment line, CRLF ends"
printf '\xef\xbb\xbf# exported\r\n0,0,0,1,1,1\r\n0.5,0.5,0.5,2,2,2\r\n' >"$tmp/bom2.csv"
run pairs --count "$tmp/bom2.csv"
printf '1\n' >"$tmp/one.count"
expect_ok "$tmp/one.count"

begin "malformed: a byte-order mark past the start is not a number"
printf '0,0,0,1,1,1\n\xef\xbb\xbf0,0,0,1,1,1\n' >"$tmp/bom3.csv"
run pairs "$tmp/bom3.csv"
expect_error 1 "bom3.csv:2:" "field 1 (min x): not a number"

begin "malformed: first line, no final newline"
printf 'x,0,0,1,1,1' >"$tmp/first.csv"
run pairs "$tmp/first.csv"
expect_error 1 "first.csv:1:" "field 1 (min x)"

begin "malformed: standard input names <stdin>"
printf '0,0,0,1,1,1\n0,0,0,1,1\n' >"$tmp/bad_stdin.csv"
run_in "$tmp/bad_stdin.csv" pairs -
expect_error 1 "<stdin>:2:"

begin "malformed: --count prints nothing either"
run pairs --count "$tmp/bad.csv"
expect_error 1 "bad.csv:4:"

# ---------------------------------------------------------------------------------------------
# Files that cannot be read: exit 1.
begin "missing file"
run pairs "$tmp/no-such-file.csv"
expect_error 1 "no-such-file.csv"

begin "directory as FILE"
run pairs "$tmp"
expect_error 1

# ---------------------------------------------------------------------------------------------
# Usage errors: exit 2.
begin "no command"
run
expect_error 2 "usage"

begin "unknown command"
run frobnicate
expect_error 2 "frobnicate"

begin "unknown top-level option"
run --frobnicate
expect_error 2 "--frobnicate"

begin "help for an unknown command"
run help frobnicate
expect_error 2 "frobnicate"

begin "pairs: unknown flag"
run pairs --frobnicate "$tmp/small.csv"
expect_error 2 "--frobnicate"

begin "pairs: unknown flag after FILE"
run pairs "$tmp/small.csv" -x
expect_error 2 "-x"

begin "pairs: missing FILE"
run pairs --count
expect_error 2 "FILE"

begin "pairs: two FILEs"
run pairs "$tmp/small.csv" "$tmp/small.csv"
expect_error 2

begin "pairs: --count takes no value"
run pairs --count=yes "$tmp/small.csv"
expect_error 2

begin "pairs: unknown backend"
run pairs --backend nope "$tmp/small.csv"
expect_error 2 "nope" "reference"

begin "pairs: empty backend"
run pairs --backend= "$tmp/small.csv"
expect_error 2

begin "pairs: unknown simd"
run pairs --simd=nope "$tmp/small.csv"
expect_error 2 "nope" "scalar"

for threads in 0 257 -1 abc 1.5 "" " 4" 4x 99999999999999999999; do
    begin "pairs: --threads '$threads'"
    run pairs "$tmp/small.csv" --threads "$threads"
    expect_error 2 "--threads"
done

for flag in --backend --simd --threads; do
    begin "pairs: $flag without a value"
    run pairs "$tmp/small.csv" "$flag"
    expect_error 2 "$flag"
done

begin "backends: unknown flag"
run backends --frobnicate
expect_error 2 "--frobnicate"

begin "backends: unexpected argument"
run backends extra
expect_error 2 "extra"

# ---------------------------------------------------------------------------------------------
# Help and version: exit 0, on stdout.
for help in --help -h help; do
    begin "bpx $help"
    run "$help"
    expect_help
done

begin "bpx --version"
run --version
if [[ $rc -ne 0 ]] || ! grep -qE '^bpx [0-9]+\.[0-9]+\.[0-9]+' "$tmp/out"; then
    fail "expected 'bpx X.Y.Z' and exit 0"
fi

# Every command listed by `bpx --help`, so commands added later are covered too.
"$bpx" --help | awk '/^commands:/ { on = 1; next } on && NF == 0 { on = 0 } on { print $1 }' \
    >"$tmp/commands"
begin "bpx --help lists pairs and backends"
if ! grep -qx pairs "$tmp/commands" || ! grep -qx backends "$tmp/commands"; then
    fail "commands section: $(tr '\n' ' ' <"$tmp/commands")"
fi
while read -r command; do
    for help in --help -h; do
        begin "bpx $command $help"
        run "$command" "$help"
        expect_help
    done
    begin "bpx help $command"
    run help "$command"
    expect_help
done <"$tmp/commands"

begin "pairs --help wins over other arguments"
run pairs "$tmp/no-such-file.csv" --help
expect_help

# ---------------------------------------------------------------------------------------------
# bpx bench, small: both parts, every backend and peer, every cycle's pairs checked (a wrong
# count exits 1), and the files --out promises.
begin "bench: both parts, small, with --out"
run bench --table2 --cycles 20 --sizes 300,3000 --seconds 0.01 --out "$tmp/bench"
if [[ $rc -ne 0 ]]; then
    fail "expected exit 0"
else
    for file in bench.md bench.csv table2.csv scale_uniform.svg scale_heavy.svg scale_resting.svg; do
        [[ -s $tmp/bench/$file ]] || fail "no $file"
    done
    grep -q "^| 500 | " "$tmp/out" || fail "no Table 2 row for n = 500"
    grep -q "^| heavy | 3000 | sap 1t |" "$tmp/out" || fail "no sap row for the heavy scene"
    grep -q "<polyline" "$tmp/bench/scale_uniform.svg" || fail "the plot has no lines"
    ! grep -q "wrong" "$tmp/out" || fail "a variant reported wrong pairs"
fi

begin "bench: --backend narrows"
run bench --sizes 1000 --scene uniform --backend prune,grid --seconds 0.01
if [[ $rc -ne 0 ]]; then
    fail "expected exit 0"
elif grep -q "| brute\|| sap" "$tmp/out" || ! grep -q "| grid 1t |" "$tmp/out"; then
    fail "expected only prune and grid rows"
fi

# --profile: a stage table per backend beside the floor (the figures are the machine's; only
# their presence is checked, and every cycle's pairs, as in the other parts).
begin "bench: --profile"
run bench --profile --sizes 3000 --threads 2 --cycles 2 --backend grid,sap,prune
if [[ $rc -ne 0 ]]; then
    fail "expected exit 0"
else
    for want in "^| random scatter (prefetched) | " "^#### grid, uniform, n = 3000, 2 threads" \
        "^| grid: scatter | " "^| grid: tests | " "^| sap: check | " "^| prune: sweep | " \
        "^| world: merge | " "^| \*\*cycle\*\* | " "Peak memory: [0-9.]* bytes a box"; do
        grep -q "$want" "$tmp/out" || fail "no line matching: $want"
    done
fi

begin "bench: unknown --backend"
run bench --backend prune,nope
expect_error 2 "nope"

begin "bench: bad --scene"
run bench --scene round
expect_error 2 "scene"

# ---------------------------------------------------------------------------------------------
# bpx query: four boxes, rays along faces, regions that touch.
printf '%s\n' '0,0,0,1,1,1' '2,0,0,3,1,1' '0,2,0,1,3,1' '1,1,1,2,2,2' >"$tmp/q.csv"

begin "query: closest ray"
run query "$tmp/q.csv" --ray 0.5,0.5,-5,0,0,1
printf '%s\n' '0 5' >"$tmp/q.expected"
expect_ok "$tmp/q.expected"

begin "query: every hit of a ray along the x axis, by fraction"
run query "$tmp/q.csv" --ray=-1,0.5,0.5,1,0,0 --all
printf '%s\n' '0 1' '1 3' >"$tmp/q.expected"
expect_ok "$tmp/q.expected"

begin "query: a region touching every box"
run query "$tmp/q.csv" --box 0.5,0.5,0.5,2,2,2
printf '%s\n' 0 1 2 3 >"$tmp/q.expected"
expect_ok "$tmp/q.expected"

begin "query: a sphere, --count"
run query "$tmp/q.csv" --sphere 1.5,1.5,1.5,0.1 --count
echo 1 >"$tmp/q.expected"
expect_ok "$tmp/q.expected"

begin "query: a swept box, every hit"
run query "$tmp/q.csv" --sweep -3,0,0,-2,1,1,10,0,0 --all
printf '%s\n' '0 0.200000003' '3 0.300000012' '1 0.400000006' >"$tmp/q.expected"
expect_ok "$tmp/q.expected"

begin "query: a batch, standard input boxes"
printf '%s\n' '# kind,numbers' 'ray,0.5,0.5,-5,0,0,1' 'box, 0,0,0,1,1,1' '' >"$tmp/batch.csv"
run_in "$tmp/q.csv" query - --batch "$tmp/batch.csv" --threads 2
printf '%s\n' '0 0 5' '1 0 0' '1 3 0' >"$tmp/q.expected"
expect_ok "$tmp/q.expected"

begin "query: NaN origin"
run query "$tmp/q.csv" --ray nan,0,0,1,0,0
expect_error 1 "origin x"

begin "query: zero direction with a length"
run query "$tmp/q.csv" --ray 0,0,0,0,0,0,1
expect_error 1 "zero direction"

begin "query: too few numbers"
run query "$tmp/q.csv" --ray 0,0
expect_error 2 "6 or 7 numbers"

begin "query: negative radius"
run query "$tmp/q.csv" --sphere 0,0,0,-1
expect_error 1 "negative"

begin "query: min > max"
run query "$tmp/q.csv" --box 1,0,0,0,1,1
expect_error 1 "min x"

begin "query: bad batch line"
printf '%s\n' 'box,0,0,0,1,1,1' 'cone,1,2' >"$tmp/batch.csv"
run query "$tmp/q.csv" --batch "$tmp/batch.csv"
expect_error 1 "batch.csv:2" "unknown query kind"

begin "query: --all without a ray"
run query "$tmp/q.csv" --box 0,0,0,1,1,1 --all
expect_error 2 "--all"

begin "query: no query"
run query "$tmp/q.csv"
expect_error 2 "give one of"

begin "query: bad box file"
printf '%s\n' '0,0,0,1,1' >"$tmp/bad.csv"
run query "$tmp/bad.csv" --box 0,0,0,1,1,1
expect_error 1 "bad.csv:1"

begin "query --help"
run query --help
expect_help

# ---------------------------------------------------------------------------------------------
if [[ $failures -ne 0 ]]; then
    echo "test_cli.sh: $failures of $cases cases FAILED" >&2
    exit 1
fi
echo "test_cli.sh: all $cases cases passed"
