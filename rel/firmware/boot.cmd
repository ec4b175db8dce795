# Neptunus A/B boot (compiled to boot.scr with mkimage by rel/firmware/build). U-Boot's distro
# boot runs it from the boot partition, on the BeagleBone (Debian's u-boot-omap, am335x_evm)
# as under qemu (u-boot-qemu, qemu_arm): it uses only what both have (no setexpr, no saveenv).
#
# The firmware's state is a few U-Boot variables kept as text in neptunus-boot.txt beside
# this script, imported into the environment here and written back with fatwrite:
#   nep_slot      the good slot, A (partition 2) or B (partition 3)
#   nep_try       the slot an update was written to
#   nep_upgrade   pending  - the update is written and verified: boot nep_try once
#                 trying   - nep_try was booted once and never marked itself good: go back
#                 failed   - went back to nep_slot; Linux records the rollback and clears it
# The running system marks nep_try good (nep_slot=nep_try, nep_upgrade unset) only when
# Neptunus is healthy: neptunus-firmware, rel/firmware/rootfs/usr/sbin/neptunus-firmware.

setenv nep_slot A
setenv nep_try
setenv nep_upgrade
# the kernel's address is free until the kernel is loaded (the script itself is at scriptaddr)
setenv nep_state_addr ${kernel_addr_r}
if load ${devtype} ${devnum}:${distro_bootpart} ${nep_state_addr} neptunus-boot.txt; then
  env import -t ${nep_state_addr} ${filesize} nep_slot nep_try nep_upgrade
fi
setenv nep_save 'env export -t ${nep_state_addr} nep_slot nep_try nep_upgrade; fatwrite ${devtype} ${devnum}:${distro_bootpart} ${nep_state_addr} neptunus-boot.txt ${filesize}'
setenv nep_fallback 'echo "neptunus: slot ${nep_try} did not come up: back to slot ${nep_slot}"; setenv nep_upgrade failed; run nep_save; setenv nep_boot ${nep_slot}'

setenv nep_boot ${nep_slot}
if test "${nep_upgrade}" = "pending"; then
  echo "neptunus: trying the update in slot ${nep_try} once"
  setenv nep_upgrade trying
  run nep_save
  setenv nep_boot ${nep_try}
elif test "${nep_upgrade}" = "trying"; then
  run nep_fallback
fi

# slot -> partition; the board's serial console and device tree, or qemu's
setenv nep_load 'if test "${nep_boot}" = "B"; then setenv nep_part 3; else setenv nep_boot A; setenv nep_part 2; fi; part uuid ${devtype} ${devnum}:${nep_part} nep_uuid && load ${devtype} ${devnum}:${nep_part} ${kernel_addr_r} /boot/vmlinuz && run nep_load_fdt && load ${devtype} ${devnum}:${nep_part} ${ramdisk_addr_r} /boot/initrd.img'
if test -n "${fdtfile}"; then
  setenv nep_console ttyS0,115200n8
  setenv nep_load_fdt 'load ${devtype} ${devnum}:${nep_part} ${fdt_addr_r} /boot/dtbs/${fdtfile} && setenv nep_fdt ${fdt_addr_r}'
else
  setenv nep_console ttyAMA0,115200
  setenv nep_load_fdt 'setenv nep_fdt ${fdtcontroladdr}'
fi

if run nep_load; then
  echo "neptunus: slot ${nep_boot} loaded"
elif test "${nep_upgrade}" = "trying"; then
  run nep_fallback
  run nep_load
fi
setenv bootargs "console=${nep_console} root=PARTUUID=${nep_uuid} rootfstype=ext4 ro rootwait panic=10 quiet neptunus.slot=${nep_boot} neptunus.upgrade=${nep_upgrade}"
echo "neptunus: booting slot ${nep_boot} (${bootargs})"
bootz ${kernel_addr_r} ${ramdisk_addr_r}:${filesize} ${nep_fdt}
