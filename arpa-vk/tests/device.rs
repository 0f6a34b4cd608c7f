//! The device layer on a real Vulkan driver (lavapipe in CI), under the Khronos validation
//! layer: any validation error or warning fails a test, including those reported while the
//! device and instance are destroyed.
//!
//! Without a Vulkan loader, driver or validation layer the tests skip with a loud message,
//! except in CI (env `CI` set), where they fail.

use arpa_vk::vk;
use arpa_vk::{AdapterChoice, ContextOptions, MemoryLocation, VkContext, VkError};

const VALIDATION: ContextOptions = ContextOptions { validation: true };

mod support;
use support::assert_clean;

/// A validated context on `choice`, or `None` (with a loud message) where Vulkan, the driver
/// or the validation layer is missing outside CI.
fn context(choice: &AdapterChoice) -> Option<VkContext> {
    context_with(choice, &VALIDATION)
}

/// [`context`] with any options.
fn context_with(choice: &AdapterChoice, options: &ContextOptions) -> Option<VkContext> {
    support::context_with("device", choice, options)
}

/// Deterministic bytes (an LCG), so a copy that drops or reorders bytes is caught.
fn pattern(len: usize, seed: u32) -> Vec<u8> {
    let mut x = seed;
    (0..len)
        .map(|_| {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (x >> 24) as u8
        })
        .collect()
}

fn is_pow2(x: u64) -> bool {
    x != 0 && x.is_power_of_two()
}

/// Checks the reported properties against what Vulkan requires and prints them.
fn check_properties(ctx: &VkContext) {
    let info = ctx.info();
    let rt = ctx.ray_tracing();
    let mem = ctx.memory();
    eprintln!("arpa-vk device: {info:#?}");
    eprintln!("arpa-vk ray-tracing properties: {rt:#?}");
    eprintln!("arpa-vk memory: {mem:#?}");
    assert!(!info.name.is_empty() && !info.driver_name.is_empty());
    assert!(info.api_version >= arpa_vk::ApiVersion { major: 1, minor: 2, patch: 0 }, "{info:?}");
    // Shader-binding-table and scratch layout: non-zero, powers of two where Vulkan requires
    // them, and within Vulkan's maxima for the alignments. (Counts are only checked non-zero:
    // lavapipe reports some below Vulkan's required minima.)
    assert!(rt.shader_group_handle_size > 0, "{rt:?}");
    assert!(is_pow2(rt.shader_group_handle_alignment.into()) && rt.shader_group_handle_alignment <= 32, "{rt:?}");
    assert!(is_pow2(rt.shader_group_base_alignment.into()) && rt.shader_group_base_alignment <= 64, "{rt:?}");
    assert!(rt.shader_group_base_alignment >= rt.shader_group_handle_alignment, "{rt:?}");
    assert!(
        is_pow2(rt.min_acceleration_structure_scratch_offset_alignment.into())
            && rt.min_acceleration_structure_scratch_offset_alignment <= 256,
        "{rt:?}"
    );
    assert!(rt.max_ray_recursion_depth >= 1, "{rt:?}");
    assert!(rt.max_shader_group_stride >= rt.shader_group_handle_size, "{rt:?}");
    assert!(rt.max_ray_dispatch_invocation_count > 0 && rt.max_ray_hit_attribute_size > 0, "{rt:?}");
    assert!(rt.max_geometry_count > 0 && rt.max_instance_count > 0 && rt.max_primitive_count > 0, "{rt:?}");
    assert!(!mem.heaps.is_empty() && mem.heaps.iter().all(|h| h.size > 0), "{mem:?}");
    assert!(mem.max_memory_allocation_size > 0 && mem.max_buffer_size != Some(0), "{mem:?}");
}

/// Creates, fills, copies, reads back and destroys buffers; every byte must come back.
fn exercise_buffers(ctx: &VkContext) {
    let device = ctx.device();

    // A device-local buffer with a device address, uploaded and read back whole and in part.
    let data = pattern(1_000_003, 7);
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS | vk::BufferUsageFlags::TRANSFER_SRC;
    let stored = ctx.upload("test storage", &data, usage).expect("upload");
    assert_eq!(stored.size(), data.len() as u64);
    assert!(stored.device_address().is_some_and(|a| a != 0), "{stored:?}");
    assert_eq!(ctx.read_back(&stored, 0, data.len() as u64).expect("read back"), data);
    assert_eq!(ctx.read_back(&stored, 12_345, 999).expect("read back part"), &data[12_345..13_344]);
    assert!(ctx.read_back(&stored, 0, 0).expect("empty read").is_empty());
    let e = ctx.read_back(&stored, 1_000_000, 4).unwrap_err();
    assert!(matches!(e, VkError::OutOfRange { offset: 1_000_000, end: 1_000_004, size: 1_000_003, .. }), "{e}");

    // Host-visible buffers: write and read through the mapping, then a device copy between
    // them and a fill recorded by hand.
    let n = 4096u64;
    let mut src = ctx.create_buffer("test host src", n, vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu).expect("host src");
    assert!(src.is_host_visible());
    let bytes = pattern(n as usize, 11);
    src.write(0, &bytes).expect("write");
    assert_eq!(src.read(0, n).expect("host read"), bytes);
    assert!(matches!(src.write(n - 1, &[1, 2]), Err(VkError::OutOfRange { .. })));
    let dst = ctx
        .create_buffer(
            "test host dst",
            2 * n,
            vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuToCpu,
        )
        .expect("host dst");
    let word = 0xA5C3_0F5Au32;
    ctx.submit_and_wait(|cmd| {
        let copy = vk::BufferCopy::default().dst_offset(n).size(n);
        let to_host =
            vk::MemoryBarrier::default().src_access_mask(vk::AccessFlags::TRANSFER_WRITE).dst_access_mask(vk::AccessFlags::HOST_READ);
        // SAFETY: both buffers are alive, large enough and have the transfer usages; the two
        // writes cover disjoint halves of `dst`.
        unsafe {
            device.cmd_fill_buffer(cmd, dst.raw(), 0, n, word);
            device.cmd_copy_buffer(cmd, src.raw(), dst.raw(), &[copy]);
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[to_host],
                &[],
                &[],
            );
        }
    })
    .expect("submit");
    let back = dst.read(0, 2 * n).expect("host read dst");
    assert!(back[..n as usize].chunks(4).all(|c| c == word.to_le_bytes()), "fill");
    assert_eq!(&back[n as usize..], &bytes[..], "copy");
    assert_eq!(ctx.read_back(&dst, n, n).expect("staged read of dst"), bytes);

    // Errors, not panics, for misuse.
    assert!(matches!(
        ctx.create_buffer("empty", 0, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly),
        Err(VkError::EmptyBuffer { .. })
    ));
    let uniform = ctx.create_buffer("test uniform", 64, vk::BufferUsageFlags::UNIFORM_BUFFER, MemoryLocation::CpuToGpu).expect("uniform");
    let e = ctx.read_back(&uniform, 0, 4).unwrap_err();
    assert!(matches!(&e, VkError::MissingUsage { usage: "TRANSFER_SRC", .. }) && e.to_string().contains("test uniform"), "{e}");

    // Many small buffers (sub-allocated from one block), some destroyed explicitly.
    let small: Vec<_> = (0..16)
        .map(|i| {
            ctx.create_buffer(&format!("test small {i}"), 256 + i * 100, vk::BufferUsageFlags::UNIFORM_BUFFER, MemoryLocation::CpuToGpu)
                .expect("small")
        })
        .collect();
    for (i, b) in small.into_iter().enumerate() {
        if i % 2 == 0 {
            b.destroy().expect("destroy");
        }
    }
    src.destroy().expect("destroy src");
}

/// Runs the full check on `choice`: properties, buffers, and no validation message during the
/// work or the teardown.
fn start_and_work(choice: &AdapterChoice) {
    let Some(ctx) = context(choice) else { return };
    eprintln!("arpa-vk test on {:?} ({}, {} {})", ctx.info().name, ctx.info().device_type, ctx.info().driver_name, ctx.info().driver_info);
    check_properties(&ctx);
    exercise_buffers(&ctx);
    let log = ctx.validation_log();
    assert_clean(&log, "while working");
    drop(ctx);
    assert_clean(&log, "while destroying the device and instance");
}

#[test]
fn auto_context_works_under_validation() {
    start_and_work(&AdapterChoice::Auto);
}

#[test]
fn lavapipe_by_name_works_under_validation() {
    let choice = AdapterChoice::NameContains("llvmpipe".into());
    if let Some(ctx) = context(&choice) {
        assert!(ctx.is_lavapipe(), "{:?}", ctx.info());
        assert_eq!(ctx.info().device_type, arpa_vk::DeviceType::Cpu);
    }
    start_and_work(&choice);
}

#[test]
fn unknown_adapter_name_is_an_error_naming_the_adapters_seen() {
    // The adapters seen, from a context that works (skips where there is no Vulkan).
    let Some(ctx) = context(&AdapterChoice::Auto) else { return };
    let present = ctx.info().name.clone();
    drop(ctx);
    let e = match VkContext::new(&AdapterChoice::NameContains("no-such-adapter".into()), &VALIDATION) {
        Ok(ctx) => panic!("an adapter named {:?} was accepted for \"no-such-adapter\"", ctx.info().name),
        Err(e) => e,
    };
    let text = e.to_string();
    eprintln!("expected error: {text}");
    match &e {
        VkError::AdapterNotFound { wanted, seen } => {
            assert_eq!(wanted, "no-such-adapter");
            assert!(seen.iter().any(|a| a.name == present), "{e}");
        }
        other => panic!("expected AdapterNotFound, got {other}"),
    }
    assert!(text.contains("no-such-adapter") && text.contains(&present), "{text}");
}

#[test]
fn more_memory_than_the_device_has_is_an_error() {
    let Some(ctx) = context(&AdapterChoice::Auto) else { return };
    let mem = ctx.memory().clone();
    let heap = mem.largest_device_local_heap().max(mem.heaps.iter().map(|h| h.size).max().unwrap_or(0));
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST;
    for (label, bytes) in [("test larger than the heap", heap + 1), ("test absurd size", u64::MAX / 2)] {
        let e = ctx.create_buffer(label, bytes, usage, MemoryLocation::GpuOnly).unwrap_err();
        eprintln!("expected error: {e}");
        match &e {
            VkError::OutOfDeviceMemory { what, bytes: b } => assert!(what == label && *b == bytes, "{e}"),
            VkError::BufferTooLarge { what, bytes: b, limit, max } => {
                assert!(what == label && *b == bytes && *max < bytes, "{e}");
                assert!(e.to_string().contains(limit), "{e}");
            }
            other => panic!("expected OutOfDeviceMemory or BufferTooLarge for {bytes} bytes, got {other}"),
        }
        assert!(e.to_string().contains(label), "{e}");
    }
    // Within every limit but above the heap: the allocator's own refusal, where the device's
    // limits allow such a request at all.
    let limit = mem.max_memory_allocation_size.min(mem.max_buffer_size.unwrap_or(u64::MAX));
    if heap < limit {
        let e = ctx.create_buffer("test within limits", heap + 1, usage, MemoryLocation::GpuOnly).unwrap_err();
        assert!(matches!(e, VkError::OutOfDeviceMemory { bytes, .. } if bytes == heap + 1), "{e}");
    } else {
        eprintln!(
            "arpa-vk: the largest heap ({heap} bytes) is not below the buffer/allocation limits ({limit} bytes): only the size error is reachable here"
        );
    }
    // The device still works afterwards.
    let data = pattern(1000, 3);
    let b = ctx.upload("test after failures", &data, vk::BufferUsageFlags::TRANSFER_SRC).expect("upload after failures");
    assert_eq!(ctx.read_back(&b, 0, 1000).expect("read back"), data);
    drop(b);
    let log = ctx.validation_log();
    drop(ctx);
    assert_clean(&log, "around failed allocations");
}

#[test]
fn the_messenger_records_validation_errors_and_leak_reports() {
    let Some(ctx) = context(&AdapterChoice::Auto) else { return };
    let device = ctx.device();
    // Invalid on purpose: a buffer without usage flags (harmless to the driver).
    let info = vk::BufferCreateInfo::default().size(64).usage(vk::BufferUsageFlags::empty());
    // SAFETY: invalid usage the validation layer reports; the buffer is never bound or used.
    let raw = unsafe { device.create_buffer(&info, None) }.expect("vkCreateBuffer");
    let messages = ctx.validation_messages();
    assert!(
        messages.iter().any(|m| m.severity == arpa_vk::Severity::Error && m.id_name.contains("VUID-VkBufferCreateInfo-usage")),
        "the validation layer did not report a buffer without usage: {messages:?}"
    );
    // SAFETY: the buffer is unused.
    unsafe { device.destroy_buffer(raw, None) };
    // A leaked buffer is reported when the device is destroyed.
    let info = vk::BufferCreateInfo::default().size(64).usage(vk::BufferUsageFlags::TRANSFER_SRC);
    // SAFETY: a valid buffer, deliberately never destroyed.
    let _leaked = unsafe { device.create_buffer(&info, None) }.expect("vkCreateBuffer");
    let log = ctx.validation_log();
    let before = log.messages().len();
    drop(ctx);
    let after = log.messages();
    assert!(
        after[before..].iter().any(|m| m.id_name.contains("vkDestroyDevice") && m.message.contains("VkBuffer")),
        "no leak report when destroying the device: {after:?}"
    );
}

#[test]
fn without_validation_nothing_is_recorded() {
    let Some(ctx) = context_with(&AdapterChoice::Auto, &ContextOptions { validation: false }) else { return };
    let data = pattern(333, 5);
    let b = ctx.upload("test unvalidated", &data, vk::BufferUsageFlags::TRANSFER_SRC).expect("upload");
    assert_eq!(ctx.read_back(&b, 0, 333).expect("read back"), data);
    assert!(ctx.validation_messages().is_empty());
}
