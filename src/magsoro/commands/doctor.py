"""``magsoro doctor [--device DEVICE] [--json] [--no-compile]``: versions, devices, memory, kernel cache, a compile
check and a CPU-vs-device parity check of a small 3D contact scene (magsoro.doctor). The first command to run on a
new machine, above all one with a GPU."""

import sys


def register(sub):
    p = sub.add_parser(
        "doctor",
        help="check this machine: versions, devices, kernel cache, CUDA compile, CPU/device parity",
        description=(
            "Report versions (magsoro, Warp, numpy, Python, OS), CPU and memory, the devices Warp sees, the CUDA "
            "driver and NVRTC, and Warp's kernel cache; then check that the engine compiles for CUDA (on the device, "
            "or PTX through NVRTC without one) and that a small 3D scene with contact and a field gradient gives the "
            "same particle positions on the CPU and on the device (without CUDA: CPU float32 against float64). "
            "Every check that could not be done is named with the reason. Exit status 0 when every check that ran "
            "passed, 1 when one failed, 2 for a bad argument (such as --device cuda on a machine without CUDA)."
        ),
    )
    p.add_argument("--device", default=None, metavar="DEVICE",
                   help="device under test: cpu, cuda or cuda:N (default: cuda when there is one, else cpu)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object on stdout (progress goes to stderr)")
    p.add_argument("--no-compile", action="store_true", help="skip the CUDA compile check")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.doctor import format_text, run_doctor, stdout_to_stderr, to_json
    from magsoro.warp_setup import quiet_warp

    quiet_warp()  # doctor prints the devices and the kernel cache itself; stdout carries only its report

    def progress(text):
        print(f"magsoro doctor: {text}", file=sys.stderr, flush=True)

    with stdout_to_stderr():
        report = run_doctor(device=args.device, compile=not args.no_compile, progress=progress)
    if args.json:
        print(to_json(report))
    else:
        print(format_text(report))
    return report["exit_code"]
