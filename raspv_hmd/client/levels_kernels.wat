;; RASPV levels stream: the page's drawing kernels (WebAssembly with 128-bit SIMD).
;; Source of levels_kernels.wasm: tools/client/build_kernels.mjs assembles it (npm wabt); the page
;; loads the .wasm file (levels_renderer.js, createCpu). All arrays live in the one memory the
;; page hands in; pointers are byte offsets, sizes are in elements.
;;
;;   add(acc, acc_w, atlas, atlas_w, x, y, w, h, ax, ay, weight)
;;       acc[(y + j) * acc_w + x + i] += weight * atlas[(ay + j) * atlas_w + ax + i]   (f32)
;;   compose(acc, fine, n, green, out)
;;       q = clamp(nearest(acc[i] + fine[i]), 0, 255) (fine = 0: none); out[i] = opaque RGBA u32,
;;       grey (q, q, q) or, with green = 1, (0, q, 0) — four pixels per SIMD step
;;   compose_up(acc, acc_w, fine, w, h, xs0, xs1, fx, ys0, ys1, fy, green, row, out)
;;       the same after OpenCV INTER_LINEAR upsampling of acc: per output row y the source rows
;;       ys0[y], ys1[y] are blended with weight fy[y] into row (acc_w floats), then per column x
;;       its columns xs0[x], xs1[x] with weight fx[x]
;;
;; nearest is round-half-to-even, as OpenCV's saturate_cast (convertScaleAbs) rounds.
(module
  (import "env" "memory" (memory 1))

  (func (export "add")
    (param $acc i32) (param $acc_w i32) (param $atlas i32) (param $atlas_w i32)
    (param $x i32) (param $y i32) (param $w i32) (param $h i32) (param $ax i32) (param $ay i32)
    (param $weight f32)
    (local $j i32) (local $o i32) (local $a i32) (local $end i32) (local $end4 i32) (local $wv v128)
    (local.set $wv (f32x4.splat (local.get $weight)))
    (local.set $j (i32.const 0))
    (block $rows_done
      (loop $rows
        (br_if $rows_done (i32.ge_s (local.get $j) (local.get $h)))
        ;; byte offsets of the row's first element in acc and atlas
        (local.set $o (i32.add (local.get $acc)
          (i32.shl (i32.add (i32.mul (i32.add (local.get $y) (local.get $j)) (local.get $acc_w)) (local.get $x)) (i32.const 2))))
        (local.set $a (i32.add (local.get $atlas)
          (i32.shl (i32.add (i32.mul (i32.add (local.get $ay) (local.get $j)) (local.get $atlas_w)) (local.get $ax)) (i32.const 2))))
        (local.set $end (i32.add (local.get $o) (i32.shl (local.get $w) (i32.const 2))))
        (local.set $end4 (i32.sub (local.get $end) (i32.const 12)))
        (block $v_done
          (loop $v
            (br_if $v_done (i32.ge_s (local.get $o) (local.get $end4)))
            (v128.store (local.get $o)
              (f32x4.add (v128.load (local.get $o)) (f32x4.mul (v128.load (local.get $a)) (local.get $wv))))
            (local.set $o (i32.add (local.get $o) (i32.const 16)))
            (local.set $a (i32.add (local.get $a) (i32.const 16)))
            (br $v)))
        (block $s_done
          (loop $s
            (br_if $s_done (i32.ge_s (local.get $o) (local.get $end)))
            (f32.store (local.get $o)
              (f32.add (f32.load (local.get $o)) (f32.mul (f32.load (local.get $a)) (local.get $weight))))
            (local.set $o (i32.add (local.get $o) (i32.const 4)))
            (local.set $a (i32.add (local.get $a) (i32.const 4)))
            (br $s)))
        (local.set $j (i32.add (local.get $j) (i32.const 1)))
        (br $rows))))

  ;; opaque RGBA of q = clamp(nearest(v), 0, 255): grey (q * 0x010101) or green (q << 8)
  (func $shade (param $v f32) (param $green i32) (result i32)
    (local $q i32)
    (local.set $q (i32.trunc_sat_f32_s (f32.nearest (local.get $v))))
    (if (i32.lt_s (local.get $q) (i32.const 0)) (then (local.set $q (i32.const 0))))
    (if (i32.gt_s (local.get $q) (i32.const 255)) (then (local.set $q (i32.const 255))))
    (i32.or (i32.const 0xff000000)
      (select (i32.shl (local.get $q) (i32.const 8)) (i32.mul (local.get $q) (i32.const 0x010101)) (local.get $green))))

  (func (export "compose")
    (param $acc i32) (param $fine i32) (param $n i32) (param $green i32) (param $out i32)
    (local $i i32) (local $end4 i32) (local $v v128) (local $q v128)
    (local.set $i (i32.const 0))
    (local.set $end4 (i32.sub (local.get $n) (i32.const 3)))
    (block $v_done
      (loop $vec
        (br_if $v_done (i32.ge_s (local.get $i) (local.get $end4)))
        (local.set $v (v128.load (i32.add (local.get $acc) (i32.shl (local.get $i) (i32.const 2)))))
        (if (local.get $fine)
          (then (local.set $v (f32x4.add (local.get $v)
            (v128.load (i32.add (local.get $fine) (i32.shl (local.get $i) (i32.const 2))))))))
        (local.set $q (i32x4.min_s (i32x4.max_s (i32x4.trunc_sat_f32x4_s (f32x4.nearest (local.get $v)))
                                                (v128.const i32x4 0 0 0 0))
                                   (v128.const i32x4 255 255 255 255)))
        (v128.store (i32.add (local.get $out) (i32.shl (local.get $i) (i32.const 2)))
          (v128.or (v128.const i32x4 0xff000000 0xff000000 0xff000000 0xff000000)
            (if (result v128) (local.get $green)
              (then (i32x4.shl (local.get $q) (i32.const 8)))
              (else (i32x4.mul (local.get $q) (v128.const i32x4 0x010101 0x010101 0x010101 0x010101))))))
        (local.set $i (i32.add (local.get $i) (i32.const 4)))
        (br $vec)))
    (block $done
      (loop $px
        (br_if $done (i32.ge_s (local.get $i) (local.get $n)))
        (local.set $v (f32x4.splat (f32.load (i32.add (local.get $acc) (i32.shl (local.get $i) (i32.const 2))))))
        (i32.store (i32.add (local.get $out) (i32.shl (local.get $i) (i32.const 2)))
          (call $shade
            (f32.add (f32x4.extract_lane 0 (local.get $v))
              (if (result f32) (local.get $fine)
                (then (f32.load (i32.add (local.get $fine) (i32.shl (local.get $i) (i32.const 2)))))
                (else (f32.const 0))))
            (local.get $green)))
        (local.set $i (i32.add (local.get $i) (i32.const 1)))
        (br $px))))

  (func (export "compose_up")
    (param $acc i32) (param $acc_w i32) (param $fine i32) (param $w i32) (param $h i32)
    (param $xs0 i32) (param $xs1 i32) (param $fx i32) (param $ys0 i32) (param $ys1 i32) (param $fy i32)
    (param $green i32) (param $row i32) (param $out i32)
    (local $x i32) (local $y i32) (local $r0 i32) (local $r1 i32) (local $wy f32) (local $c i32)
    (local $a i32) (local $p f32) (local $v f32) (local $o i32)
    (local.set $o (i32.const 0))
    (local.set $y (i32.const 0))
    (block $rows_done
      (loop $rows
        (br_if $rows_done (i32.ge_s (local.get $y) (local.get $h)))
        ;; the two source rows blended vertically into row[]
        (local.set $r0 (i32.add (local.get $acc) (i32.shl (i32.mul (i32.load (i32.add (local.get $ys0)
          (i32.shl (local.get $y) (i32.const 2)))) (local.get $acc_w)) (i32.const 2))))
        (local.set $r1 (i32.add (local.get $acc) (i32.shl (i32.mul (i32.load (i32.add (local.get $ys1)
          (i32.shl (local.get $y) (i32.const 2)))) (local.get $acc_w)) (i32.const 2))))
        (local.set $wy (f32.load (i32.add (local.get $fy) (i32.shl (local.get $y) (i32.const 2)))))
        (local.set $c (i32.const 0))
        (block $blend_done
          (loop $blend
            (br_if $blend_done (i32.ge_s (local.get $c) (local.get $acc_w)))
            (local.set $p (f32.load (i32.add (local.get $r0) (i32.shl (local.get $c) (i32.const 2)))))
            (f32.store (i32.add (local.get $row) (i32.shl (local.get $c) (i32.const 2)))
              (f32.add (local.get $p) (f32.mul (f32.sub (f32.load (i32.add (local.get $r1) (i32.shl (local.get $c) (i32.const 2))))
                                                        (local.get $p)) (local.get $wy))))
            (local.set $c (i32.add (local.get $c) (i32.const 1)))
            (br $blend)))
        ;; then along the row
        (local.set $x (i32.const 0))
        (block $cols_done
          (loop $cols
            (br_if $cols_done (i32.ge_s (local.get $x) (local.get $w)))
            (local.set $a (i32.add (local.get $row) (i32.shl (i32.load (i32.add (local.get $xs0) (i32.shl (local.get $x) (i32.const 2)))) (i32.const 2))))
            (local.set $p (f32.load (local.get $a)))
            (local.set $v (f32.add (local.get $p)
              (f32.mul (f32.sub (f32.load (i32.add (local.get $row) (i32.shl (i32.load (i32.add (local.get $xs1)
                (i32.shl (local.get $x) (i32.const 2)))) (i32.const 2)))) (local.get $p))
                (f32.load (i32.add (local.get $fx) (i32.shl (local.get $x) (i32.const 2)))))))
            (if (local.get $fine)
              (then (local.set $v (f32.add (local.get $v)
                (f32.load (i32.add (local.get $fine) (i32.shl (local.get $o) (i32.const 2))))))))
            (i32.store (i32.add (local.get $out) (i32.shl (local.get $o) (i32.const 2)))
              (call $shade (local.get $v) (local.get $green)))
            (local.set $o (i32.add (local.get $o) (i32.const 1)))
            (local.set $x (i32.add (local.get $x) (i32.const 1)))
            (br $cols)))
        (local.set $y (i32.add (local.get $y) (i32.const 1)))
        (br $rows))))

)
