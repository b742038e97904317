//! A V4L2 camera's node opened for its controls, beside the GStreamer source (as `v4l2-ctl`
//! does): the kernel's four control ioctls on their stable structures (`linux/videodev2.h`).

use super::Control;
use std::os::fd::{AsRawFd, OwnedFd};
use std::path::{Path, PathBuf};

/// Why a camera's controls could not be reached.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    #[error("camera {}: cannot open it for its controls: {source}", .path.display())]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("camera {}: setting {name} (0x{id:08x}) to {value}: {source}", .path.display())]
    Set {
        path: PathBuf,
        id: u32,
        name: String,
        value: i64,
        source: std::io::Error,
    },
    #[error("camera {}: reading control 0x{id:08x}: {source}", .path.display())]
    Get {
        path: PathBuf,
        id: u32,
        source: std::io::Error,
    },
}

impl DeviceError {
    /// Whether the camera is gone (unplugged): open it again.
    pub fn gone(&self) -> bool {
        let e = match self {
            DeviceError::Open { source, .. }
            | DeviceError::Set { source, .. }
            | DeviceError::Get { source, .. } => source,
        };
        matches!(
            e.raw_os_error(),
            Some(libc::ENODEV | libc::ENXIO | libc::EBADF)
        )
    }
}

/// A V4L2 device node opened for its controls.
pub struct Device {
    fd: OwnedFd,
    path: PathBuf,
}

#[repr(C)]
struct QueryCtrl {
    id: u32,
    kind: u32,
    name: [u8; 32],
    minimum: i32,
    maximum: i32,
    step: i32,
    default_value: i32,
    flags: u32,
    reserved: [u32; 2],
}

#[repr(C, packed)]
struct QueryMenu {
    id: u32,
    index: u32,
    name: [u8; 32],
    reserved: u32,
}

#[repr(C)]
struct ControlValue {
    id: u32,
    value: i32,
}

/// `_IOWR('V', nr, T)`.
const fn iowr<T>(nr: u64) -> u64 {
    (3 << 30) | ((std::mem::size_of::<T>() as u64) << 16) | ((b'V' as u64) << 8) | nr
}
const VIDIOC_G_CTRL: u64 = iowr::<ControlValue>(27);
const VIDIOC_S_CTRL: u64 = iowr::<ControlValue>(28);
const VIDIOC_QUERYCTRL: u64 = iowr::<QueryCtrl>(36);
const VIDIOC_QUERYMENU: u64 = iowr::<QueryMenu>(37);
const CTRL_FLAG_NEXT_CTRL: u32 = 0x8000_0000;
const CTRL_FLAG_DISABLED: u32 = 0x0001;
const CTRL_TYPE_MENU: u32 = 3;
const CTRL_TYPE_CLASS: u32 = 6;

impl Device {
    pub fn open(path: &Path) -> Result<Device, DeviceError> {
        use std::os::unix::fs::OpenOptionsExt;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .map_err(|source| DeviceError::Open {
                path: path.into(),
                source,
            })?;
        Ok(Device {
            fd: file.into(),
            path: path.into(),
        })
    }

    fn ioctl<T>(&self, request: u64, arg: &mut T) -> std::io::Result<()> {
        // SAFETY: `arg` is the structure `request` names, as linux/videodev2.h lays it out.
        let r = unsafe { libc::ioctl(self.fd.as_raw_fd(), request as _, arg as *mut T) };
        if r < 0 {
            Err(std::io::Error::last_os_error())
        } else {
            Ok(())
        }
    }

    /// Every enabled control the device reports, menus with their items.
    pub fn controls(&self) -> Vec<Control> {
        let mut out = vec![];
        let mut id = CTRL_FLAG_NEXT_CTRL;
        loop {
            // SAFETY: plain integers and bytes; all zero is a valid value.
            let mut q: QueryCtrl = unsafe { std::mem::zeroed() };
            q.id = id;
            if self.ioctl(VIDIOC_QUERYCTRL, &mut q).is_err() {
                return out;
            }
            id = q.id | CTRL_FLAG_NEXT_CTRL;
            if q.flags & CTRL_FLAG_DISABLED != 0 || q.kind == CTRL_TYPE_CLASS {
                continue;
            }
            let name = String::from_utf8_lossy(&q.name)
                .trim_end_matches('\0')
                .to_string();
            let menu = if q.kind == CTRL_TYPE_MENU {
                (q.minimum..=q.maximum)
                    .filter(|&i| {
                        // SAFETY: as above.
                        let mut m: QueryMenu = unsafe { std::mem::zeroed() };
                        (m.id, m.index) = (q.id, i as u32);
                        self.ioctl(VIDIOC_QUERYMENU, &mut m).is_ok()
                    })
                    .map(i64::from)
                    .collect()
            } else {
                vec![]
            };
            out.push(Control {
                id: q.id,
                name,
                min: q.minimum.into(),
                max: q.maximum.into(),
                step: q.step.into(),
                default: q.default_value.into(),
                menu,
            });
        }
    }

    pub fn get(&self, id: u32) -> Result<i64, DeviceError> {
        let mut c = ControlValue { id, value: 0 };
        self.ioctl(VIDIOC_G_CTRL, &mut c)
            .map_err(|source| DeviceError::Get {
                path: self.path.clone(),
                id,
                source,
            })?;
        Ok(c.value.into())
    }

    pub fn set(&self, controls: &[Control], id: u32, value: i64) -> Result<(), DeviceError> {
        let mut c = ControlValue {
            id,
            value: value as i32,
        };
        self.ioctl(VIDIOC_S_CTRL, &mut c)
            .map_err(|source| DeviceError::Set {
                path: self.path.clone(),
                id,
                name: controls
                    .iter()
                    .find(|c| c.id == id)
                    .map_or_else(String::new, |c| c.name.clone()),
                value,
                source,
            })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_device_is_a_clear_error() {
        let e = Device::open(Path::new("/dev/video-that-is-not-there"))
            .err()
            .unwrap();
        assert_eq!(
            e.to_string(),
            "camera /dev/video-that-is-not-there: cannot open it for its controls: \
             No such file or directory (os error 2)"
        );
    }

    #[test]
    fn the_ioctl_numbers_are_the_kernels() {
        assert_eq!(VIDIOC_QUERYCTRL, 0xc044_5624);
        assert_eq!(VIDIOC_QUERYMENU, 0xc02c_5625);
        assert_eq!(VIDIOC_G_CTRL, 0xc008_561b);
        assert_eq!(VIDIOC_S_CTRL, 0xc008_561c);
    }
}
