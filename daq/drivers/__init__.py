"""Real device drivers: NI-DAQmx strain + potentiometer, the OpenCV camera (device, video
file, folder of stills) and the EXIF reader it uses. Vendor SDKs are imported lazily."""
